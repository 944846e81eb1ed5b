//! The generator's integration tests, one binary: a module per concern
//! (`cargo test -p generator --test it render_device` runs one).

mod catalog_builtin;
mod catalog_cli;
mod catalog_geometry;
mod catalog_meshio;
mod catalog_validation;
mod catalog_ycb;
mod cli_conventions;
mod config_limits;
mod dataset_integrity;
mod plan_catalog;
mod plan_cli;
mod plan_conditions;
mod plan_configs;
mod plan_levers;
mod plan_numerics;
mod plan_support;
mod render_cli;
mod render_common;
mod render_dataset;
mod render_device;
mod render_faults;
mod render_head;
mod render_levers;
mod render_lock;
mod render_parts;
mod render_resume;
mod render_world;
