//! What the kernel's unit tests share: a seeded pseudo-random sequence, so that a failing
//! case comes back on every run without a random-number crate in a `no_std` kernel.

/// Marsaglia's xorshift32 from `seed` (non-zero): the same numbers on every run.
pub fn xorshift(seed: u32) -> impl FnMut() -> u32 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    }
}
