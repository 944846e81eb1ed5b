//! Library side of `grasp-gen`: the object catalog, reach planning, rendering
//! orchestration and the dataset writer.

pub mod catalog;
pub mod python;
