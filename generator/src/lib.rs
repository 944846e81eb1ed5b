//! Library side of `grasp-gen`: the object catalog, reach planning, rendering
//! orchestration and the dataset writer.

pub mod appearance;
pub mod catalog;
pub mod config;
pub mod dataset;
pub mod geometry;
pub mod look;
pub mod plan;
pub mod python;
pub mod randomize;
pub mod raster;
pub mod render;
pub mod unseen_look;
