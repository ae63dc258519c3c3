//! Where a ray's result goes, as every ray, hit and result message carries it.

/// `Reply::light` of a ray that is not a shadow ray.
pub const NO_LIGHT: u8 = u8::MAX;
/// `Reply::home` of a primary ray not yet adopted by a node (centralized generation).
pub const NO_HOME: u16 = u16::MAX;

/// Where a ray's result goes: the pixel record `slot` on node `home`, part `hit` (and `light`
/// for a shadow ray).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    /// The node holding the pixel record.
    pub home: u16,
    /// The record's slot there.
    pub slot: u16,
    /// For primary and transparency rays the index of the next hit; for shadow rays the hit
    /// they light.
    pub hit: u8,
    /// For shadow rays the light; otherwise [`NO_LIGHT`].
    pub light: u8,
}
