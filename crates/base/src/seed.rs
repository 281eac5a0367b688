//! Seed derivation: every random stream of a run (a round's draws, a grasp source, a trial's
//! views) gets its own seed from the run's base seed, a tag naming the stream and up to two
//! indices, so streams never overlap and adding one never shifts another.
//!
//! ```
//! use lgdm_base::seed::{derive_seed, splitmix64};
//! assert_eq!(splitmix64(0), 0xE220_A839_7B1D_CDAF);
//! assert_eq!(derive_seed(1, 2, 3, 4), derive_seed(1, 2, 3, 4));
//! assert_ne!(derive_seed(1, 2, 3, 4), derive_seed(1, 2, 4, 3));
//! ```

/// The SplitMix64 step: mixes a 64-bit value into a well-distributed one.
pub fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The seed of the stream `tag` at indices `a`, `b` of a run with base seed `seed`.
pub fn derive_seed(seed: u64, tag: u64, a: u64, b: u64) -> u64 {
    splitmix64(
        splitmix64(splitmix64(seed ^ splitmix64(tag)) ^ a) ^ b.wrapping_mul(0x2545_F491_4F6C_DD1D),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbouring_streams_differ_in_many_bits() {
        for (a, b) in [(0, 1), (1, 2), (100, 101)] {
            let x = derive_seed(0, 1, a, 0) ^ derive_seed(0, 1, b, 0);
            assert!(x.count_ones() > 16, "{a} vs {b}: {x:x}");
            let y = derive_seed(0, a, 0, 0) ^ derive_seed(0, b, 0, 0);
            assert!(y.count_ones() > 16, "tags {a} vs {b}: {y:x}");
        }
    }
}
