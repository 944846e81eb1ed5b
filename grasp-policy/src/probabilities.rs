//! The validation every model output goes through before it may vote: a
//! probability vector, finite, each in [0, 1], summing to 1.

use grasp_schema::taxonomy::Class;

/// Why a model output was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidOutput {
    #[error("class {class} has a non-finite probability ({value})")]
    NonFinite { class: Class, value: f32 },
    #[error("class {class} has probability {value}, outside [0, 1]")]
    OutOfRange { class: Class, value: f32 },
    #[error("probabilities sum to {sum}, not 1")]
    BadSum { sum: f32 },
}

/// A validated probability vector: finite, each in [0, 1], summing to 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probabilities([f32; Class::COUNT]);

/// Tolerance on the sum (f32 softmax rounding stays far below it).
const SUM_TOLERANCE: f32 = 1e-3;

impl Probabilities {
    pub fn new(p: [f32; Class::COUNT]) -> Result<Self, InvalidOutput> {
        for (class, &value) in Class::ALL.iter().zip(&p) {
            if !value.is_finite() {
                return Err(InvalidOutput::NonFinite {
                    class: *class,
                    value,
                });
            }
            if !(-SUM_TOLERANCE..=1.0 + SUM_TOLERANCE).contains(&value) {
                return Err(InvalidOutput::OutOfRange {
                    class: *class,
                    value,
                });
            }
        }
        // Pairwise-free: five terms in f64 cannot lose precision that matters.
        let sum = p.iter().map(|&v| f64::from(v)).sum::<f64>() as f32;
        if (sum - 1.0).abs() > SUM_TOLERANCE {
            return Err(InvalidOutput::BadSum { sum });
        }
        Ok(Probabilities(p))
    }

    pub fn as_array(&self) -> &[f32; Class::COUNT] {
        &self.0
    }

    pub fn get(&self, c: Class) -> f32 {
        self.0[c.index()]
    }

    /// The most probable class; ties go to the lower index.
    pub fn argmax(&self) -> (Class, f32) {
        let mut best = (Class::ALL[0], self.0[0]);
        for (c, &v) in Class::ALL.iter().zip(&self.0).skip(1) {
            if v > best.1 {
                best = (*c, v);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_a_distribution_and_finds_its_argmax() {
        let p = Probabilities::new([0.1, 0.6, 0.1, 0.1, 0.1]).unwrap();
        assert_eq!(p.argmax(), (Class::Lateral, 0.6));
        let tie = Probabilities::new([0.5, 0.0, 0.5, 0.0, 0.0]).unwrap();
        assert_eq!(tie.argmax().0, Class::Power);
    }

    #[test]
    fn refuses_nan_inf_negative_and_unnormalised_outputs() {
        let nan = Probabilities::new([f32::NAN, 0.25, 0.25, 0.25, 0.25]);
        assert!(matches!(
            nan,
            Err(InvalidOutput::NonFinite {
                class: Class::Power,
                ..
            })
        ));
        let inf = Probabilities::new([0.0, 0.0, 0.0, 0.0, f32::INFINITY]);
        assert!(matches!(
            inf,
            Err(InvalidOutput::NonFinite {
                class: Class::NoGrasp,
                ..
            })
        ));
        let neg = Probabilities::new([1.5, -0.5, 0.0, 0.0, 0.0]);
        assert!(matches!(neg, Err(InvalidOutput::OutOfRange { .. })));
        let logits = Probabilities::new([0.9, 0.9, 0.0, 0.0, 0.0]);
        assert!(matches!(logits, Err(InvalidOutput::BadSum { .. })));
    }
}
