//! Machine profiles: what each of the kernel's counted operations costs on a machine, what a
//! message costs, and how much memory a node has. Profiles are TOML files shipped with voxcube
//! (`hostsim/profiles/`), selectable by name (`ncube2`, `modern`) or read from a path.
//!
//! Invariants: every cost is finite and non-negative, `scale` and `node_memory` positive. The
//! time of a piece of work is `scale × Σ count × cost`, a message's software costs are times
//! `message_scale`; those two are the fitted numbers ([`crate::experiments::fit`]).

use serde::Deserialize;
use std::path::Path;

/// Per-operation costs, seconds (before `scale`).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Costs {
    /// Stepping to one lattice sample.
    pub sample: f64,
    /// Testing a sample's owner plane against the node's slab, which a worker does on every
    /// sample to find where its ray leaves; the sequential tracer (Table 1's one node,
    /// [`MachineProfile::sequential`]) knows that from the ray's box clip and does not.
    pub slab_test: f64,
    /// One trilinear interpolation.
    pub interpolation: f64,
    /// One nearest-node read.
    pub lookup: f64,
    /// One refinement evaluation (beyond its interpolation).
    pub refinement: f64,
    /// One gradient (beyond its interpolations).
    pub gradient: f64,
    /// Shading one point.
    pub shading: f64,
    /// One crossing test: one taken sample against one surface (Voxel_Sample's threshold
    /// search runs it for every sample, crossing or not).
    pub crossing: f64,
    /// One procedure call and return: the tracer calls its interpolation routine for every
    /// interpolation and its sample routine for every sample (the paper's Interpolate and
    /// Voxel_Sample, profiled as routines), each call priced in its routine's line.
    pub call: f64,
    /// Setting up one primary ray and testing it for its first slab, on every node that does
    /// ([`voxcube_kernel::counters::Counters::rays_set_up`]): without row leaps, every node
    /// of a ring for every pixel of its cluster's rows, the paper's distributed generation.
    pub ray_setup: f64,
}

/// Message costs, seconds (before `scale`).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MessageCosts {
    /// Start-up of one message.
    pub latency: f64,
    /// Per byte on a link.
    pub per_byte: f64,
    /// Per hop beyond the first.
    pub per_hop: f64,
    /// Reading one message from the buffer.
    pub read: f64,
    /// Writing one message.
    pub write: f64,
    /// One test of the buffer...
    pub test: f64,
    /// ...plus this per pending message.
    pub test_per_pending: f64,
}

/// A machine profile.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MachineProfile {
    /// Name.
    pub name: String,
    /// Bytes of memory per node.
    pub node_memory: usize,
    /// The fitted factor on the tracer's compute costs [`Costs`].
    pub scale: f64,
    /// The fitted factor on the message primitives' software costs (start-up, `nread`,
    /// `nwrite`, `ntest`); a link's per-byte and per-hop costs are the hardware's own and
    /// stay. 1 when absent.
    #[serde(default = "one")]
    pub message_scale: f64,
    /// Operation costs.
    pub costs: Costs,
    /// Message costs.
    pub messages: MessageCosts,
}

fn one() -> f64 {
    1.0
}

/// The profiles shipped with voxcube.
pub const BUILT_IN: [(&str, &str); 2] = [
    ("ncube2", include_str!("../profiles/ncube2.toml")),
    ("modern", include_str!("../profiles/modern.toml")),
];

/// Why a profile cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// No built-in profile of that name and no such file.
    #[error("unknown machine \"{0}\": give ncube2, modern, or a profile file (.toml)")]
    Unknown(String),
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a valid profile.
    #[error("{file}: {message}")]
    Invalid {
        /// The file.
        file: String,
        /// What is wrong.
        message: String,
    },
}

impl MachineProfile {
    /// A built-in profile by name, or a profile file by path.
    pub fn load(name_or_path: &str) -> Result<MachineProfile, ProfileError> {
        if let Some((_, text)) = BUILT_IN.iter().find(|(n, _)| *n == name_or_path) {
            return MachineProfile::parse(text, name_or_path);
        }
        let path = Path::new(name_or_path);
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            return Err(ProfileError::Unknown(name_or_path.to_string()));
        }
        let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Read {
            file: name_or_path.to_string(),
            source,
        })?;
        MachineProfile::parse(&text, name_or_path)
    }

    /// Parse and check profile text.
    pub fn parse(text: &str, file: &str) -> Result<MachineProfile, ProfileError> {
        let invalid = |message: String| ProfileError::Invalid {
            file: file.to_string(),
            message,
        };
        let p: MachineProfile =
            toml::from_str(text).map_err(|e| invalid(e.to_string().trim_end().to_string()))?;
        let c = &p.costs;
        let m = &p.messages;
        let named = [
            ("costs.sample", c.sample),
            ("costs.slab_test", c.slab_test),
            ("costs.interpolation", c.interpolation),
            ("costs.lookup", c.lookup),
            ("costs.refinement", c.refinement),
            ("costs.gradient", c.gradient),
            ("costs.shading", c.shading),
            ("costs.crossing", c.crossing),
            ("costs.call", c.call),
            ("costs.ray_setup", c.ray_setup),
            ("messages.latency", m.latency),
            ("messages.per_byte", m.per_byte),
            ("messages.per_hop", m.per_hop),
            ("messages.read", m.read),
            ("messages.write", m.write),
            ("messages.test", m.test),
            ("messages.test_per_pending", m.test_per_pending),
        ];
        if let Some((key, v)) = named.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            return Err(invalid(format!(
                "{key}: {v} must be a finite number of seconds >= 0"
            )));
        }
        for (key, v) in [("scale", p.scale), ("message_scale", p.message_scale)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(format!("{key}: {v} must be > 0")));
            }
        }
        if p.node_memory == 0 {
            return Err(invalid("node_memory must be > 0".into()));
        }
        Ok(p)
    }

    /// Unscaled seconds of the tracer's compute for counted work `c` of a view searching
    /// `surfaces` iso-surfaces (0 for a composited view), as the paper's Table 4 splits it:
    /// interpolation, tracing (stepping), sample-and-shade (a crossing test per taken sample
    /// and surface, refinement, gradients, shading), and generation (setting up primary rays
    /// to find where they start, which the paper's table does not list).
    /// Multiply by `scale` for machine time.
    pub fn compute(&self, c: &voxcube_kernel::counters::Counters, surfaces: u32) -> [f64; 4] {
        self.priced(c, surfaces, self.costs.slab_test)
    }

    /// Unscaled seconds of counted work `c` done by the paper's sequential tracer, which the
    /// paper's one-node time is taken to be: [`MachineProfile::compute`] without a slab test
    /// on every sample (and, being one program on one node, no messages). The paper's rows of
    /// 2 to 16 nodes in clusters of 1 spend 7% more node-seconds than its one node, where a
    /// worker on every node does the same work as the one node but for those tests.
    pub fn sequential(&self, c: &voxcube_kernel::counters::Counters, surfaces: u32) -> [f64; 4] {
        self.priced(c, surfaces, 0.0)
    }

    fn priced(
        &self,
        c: &voxcube_kernel::counters::Counters,
        surfaces: u32,
        slab_test: f64,
    ) -> [f64; 4] {
        let k = &self.costs;
        let n = |v: u64| v as f64;
        [
            n(c.interpolations) * (k.interpolation + k.call) + n(c.lookups) * (k.lookup + k.call),
            n(c.samples) * (k.sample + slab_test),
            n(c.refinements) * k.refinement
                + n(c.gradients) * k.gradient
                + n(c.shadings) * k.shading
                + n(c.samples) * (f64::from(surfaces) * k.crossing + k.call),
            n(c.rays_set_up) * k.ray_setup,
        ]
    }

    /// What messages cost on this machine: the profile's message costs with their software
    /// parts times [`MachineProfile::message_scale`].
    pub fn message_costs(&self) -> MessageCosts {
        let (m, f) = (self.messages, self.message_scale);
        MessageCosts {
            latency: m.latency * f,
            read: m.read * f,
            write: m.write * f,
            test: m.test * f,
            test_per_pending: m.test_per_pending * f,
            ..m
        }
    }

    /// The iso-surfaces `view` tests every taken sample against (none when compositing).
    pub fn searched_surfaces(view: &voxcube_kernel::trace::view::View) -> u32 {
        match &view.spec().mode {
            voxcube_kernel::trace::view::Mode::Surfaces(s) => s.len() as u32,
            voxcube_kernel::trace::view::Mode::Composite(_) => 0,
        }
    }

    /// The nCUBE 2.
    pub fn ncube2() -> MachineProfile {
        // The shipped file is checked by a test; a broken one is a build defect.
        #[allow(
            clippy::expect_used,
            reason = "the shipped profile is valid; a test checks it"
        )]
        MachineProfile::load("ncube2").expect("the shipped ncube2 profile is valid")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_profiles_load_and_bad_ones_name_the_key() {
        for (name, _) in BUILT_IN {
            let p = MachineProfile::load(name).unwrap();
            assert_eq!(p.name, name);
        }
        assert_eq!(MachineProfile::ncube2().node_memory, 4 << 20);
        let bad =
            include_str!("../profiles/ncube2.toml").replace("sample = 2.9e-6", "sample = -1.0");
        let e = MachineProfile::parse(&bad, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("costs.sample"), "{e}");
        let e = MachineProfile::parse("name = 1", "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.toml"), "{e}");
        assert!(matches!(
            MachineProfile::load("cray"),
            Err(ProfileError::Unknown(_))
        ));
        let bad = include_str!("../profiles/ncube2.toml")
            .replace("message_scale = 0.25", "message_scale = 0.0");
        let e = MachineProfile::parse(&bad, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("message_scale"), "{e}");
    }

    #[test]
    fn every_taken_sample_pays_a_crossing_test_per_surface() {
        let p = MachineProfile::ncube2();
        let c = voxcube_kernel::counters::Counters {
            samples: 1000,
            crossings: 3,
            ..Default::default()
        };
        let [_, _, none, _] = p.compute(&c, 0);
        let [_, _, two, _] = p.compute(&c, 2);
        // Each sample calls the sample routine, surfaces or not; crossings found cost nothing
        // beyond their refinement.
        let calls = 1000.0 * p.costs.call;
        assert!((none - calls).abs() < 1e-15, "{none}");
        assert!(
            (two - calls - 2000.0 * p.costs.crossing).abs() < 1e-15,
            "{two}"
        );
    }

    #[test]
    fn message_scale_scales_the_software_and_leaves_the_links() {
        let p = MachineProfile {
            message_scale: 3.0,
            ..MachineProfile::ncube2()
        };
        let (m, f) = (p.message_costs(), p.messages);
        for (scaled, given) in [
            (m.latency, f.latency),
            (m.read, f.read),
            (m.write, f.write),
            (m.test, f.test),
            (m.test_per_pending, f.test_per_pending),
        ] {
            assert!((scaled - 3.0 * given).abs() < 1e-15);
        }
        assert_eq!((m.per_byte, m.per_hop), (f.per_byte, f.per_hop));
    }
}
