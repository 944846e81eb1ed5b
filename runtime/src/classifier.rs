//! Per-frame classification: the [`FrameClassifier`] trait the decision loop
//! runs on, and the validation every model output goes through before it may
//! influence the hand.

use grasp_model::error::ModelError;
use grasp_schema::taxonomy::Class;
use image::RgbImage;

pub use grasp_policy::{InvalidOutput, Probabilities};

/// Anything that turns one camera frame into class probabilities, indexed by
/// [`Class`] (power 0, lateral 1, pinch 2, pinch3 3, no_grasp 4). A
/// classifier with the approach's history (a trace head) keeps it from
/// [`FrameClassifier::begin_approach`] on, each frame at its `time_s`
/// (seconds, ascending within an approach).
pub trait FrameClassifier {
    fn classify(
        &mut self,
        frame: &RgbImage,
        time_s: f64,
    ) -> Result<[f32; Class::COUNT], ClassifyError>;

    /// A new approach begins: forget the frames of the last one.
    fn begin_approach(&mut self) {}
}

/// Why a frame got no output at all (an output that is not a distribution
/// is an [`InvalidOutput`]).
#[derive(Debug, thiserror::Error)]
pub enum ClassifyError {
    /// The model failed on the frame (its input, a tensor operation).
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("classifier returned {got} outputs for one frame")]
    Outputs { got: usize },
}

impl<T: FrameClassifier + ?Sized> FrameClassifier for Box<T> {
    fn classify(
        &mut self,
        frame: &RgbImage,
        time_s: f64,
    ) -> Result<[f32; Class::COUNT], ClassifyError> {
        (**self).classify(frame, time_s)
    }

    fn begin_approach(&mut self) {
        (**self).begin_approach()
    }
}

/// Numerically stable softmax (log-sum-exp), for classifiers that return
/// logits. Non-finite inputs propagate and are caught by validation.
pub fn softmax(logits: [f32; Class::COUNT]) -> [f32; Class::COUNT] {
    let max = logits.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let exps = logits.map(|l| (l - max).exp());
    let total: f32 = exps.iter().sum();
    exps.map(|e| e / total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn softmax_is_stable_for_extreme_logits() {
        let p = softmax([1000.0, 0.0, -1000.0, 999.0, f32::MIN / 2.0]);
        let v = Probabilities::new(p).expect("valid");
        assert_eq!(v.argmax().0, Class::Power);
        assert!((p[0] - 1.0 / (1.0 + (-1.0f32).exp())).abs() < 1e-6);
        assert!(Probabilities::new(softmax([f32::NAN, 0.0, 0.0, 0.0, 0.0])).is_err());
    }
}
