//! Training and evaluation of the pre-shape classifier.

pub mod model;
