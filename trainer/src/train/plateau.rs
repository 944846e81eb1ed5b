//! The learning-rate schedule and early stop: PyTorch's ReduceLROnPlateau.

/// PyTorch's ReduceLROnPlateau (mode min, relative threshold 1e-4) plus
/// early stopping on the same improvement test.
#[derive(Debug, Clone)]
pub struct Plateau {
    pub best: f64,
    bad_epochs: usize,
    since_best: usize,
    patience: usize,
    factor: f64,
    stop_after: usize,
}

/// What the scheduler decided after an epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateauStep {
    pub improved: bool,
    pub new_lr: Option<f64>,
    pub stop: bool,
}

impl Plateau {
    pub fn new(patience: usize, factor: f64, stop_after: usize) -> Self {
        Plateau {
            best: f64::INFINITY,
            bad_epochs: 0,
            since_best: 0,
            patience,
            factor,
            stop_after,
        }
    }

    pub fn step(&mut self, val_loss: f64, lr: f64) -> PlateauStep {
        let improved = val_loss < self.best * (1.0 - 1e-4) || self.best.is_infinite();
        let mut new_lr = None;
        if improved {
            self.best = val_loss;
            self.bad_epochs = 0;
            self.since_best = 0;
        } else {
            self.bad_epochs += 1;
            self.since_best += 1;
            if self.bad_epochs > self.patience {
                new_lr = Some(lr * self.factor);
                self.bad_epochs = 0;
            }
        }
        PlateauStep {
            improved,
            new_lr,
            stop: self.since_best >= self.stop_after,
        }
    }
}
