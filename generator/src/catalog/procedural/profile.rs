//! Members of a procedural model's family: the same object with another
//! handle or rim profile (`[randomize.profiles]`). Real mugs, pitchers,
//! plates and tools differ from one another in the cross-section and span
//! of their handles and in the shape of their rims more than in size; one
//! model per object teaches one of each.
//!
//! Member 0 is the catalog's model, bit for bit. Member `k > 0` draws six
//! numbers in [-1, 1] from a stream named after the shape's kind, so a
//! member is the same mesh in every dataset and on every machine; each
//! kind reads them as its own parameters (`vessels`, `tools`), within
//! ranges that keep the catalog's part boxes on the part.

use grasp_schema::plan::substream_seed;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Six draws in [-1, 1] that a kind maps onto its profile's parameters; all
/// zero for the catalog's model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile([f64; 6]);

impl Profile {
    /// The catalog's model: every parameter at its catalog value.
    pub const MODEL: Profile = Profile([0.0; 6]);

    /// Member `variant` of the family of shapes of `kind` (0: the model).
    pub fn member(kind: &str, variant: u32) -> Profile {
        if variant == 0 {
            return Profile::MODEL;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(substream_seed(u64::from(variant), kind));
        Profile(std::array::from_fn(|_| rng.gen_range(-1.0..=1.0)))
    }

    /// `1 + spread * draw[i]`: a factor on a catalog value (exactly 1 for
    /// the model).
    pub fn factor(&self, i: usize, spread: f64) -> f64 {
        1.0 + spread * self.0[i]
    }

    /// `2^(octaves * draw[i])`: a log-symmetric factor, for exponents.
    pub fn octaves(&self, i: usize, octaves: f64) -> f64 {
        (octaves * self.0[i]).exp2()
    }

    /// `by * draw[i]`: an offset from a catalog value (exactly 0 for the
    /// model).
    pub fn shift(&self, i: usize, by: f64) -> f64 {
        by * self.0[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_is_member_zero_and_leaves_every_value_as_it_is() {
        let m = Profile::member("mug", 0);
        assert_eq!(m, Profile::MODEL);
        for i in 0..6 {
            assert_eq!(m.factor(i, 0.35), 1.0);
            assert_eq!(m.octaves(i, 0.8), 1.0);
            assert_eq!(m.shift(i, 0.08), 0.0);
        }
    }

    #[test]
    fn members_are_fixed_by_kind_and_index_and_differ_from_each_other() {
        let a = Profile::member("mug", 3);
        assert_eq!(a, Profile::member("mug", 3));
        assert_ne!(a, Profile::member("mug", 4));
        assert_ne!(a, Profile::member("plate", 3));
        for p in (1..50).map(|k| Profile::member("spoon", k)) {
            assert!(p.0.iter().all(|d| (-1.0..=1.0).contains(d)), "{p:?}");
            assert_ne!(p, Profile::MODEL);
        }
    }
}
