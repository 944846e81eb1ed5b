//! The trainer's integration tests, one binary: a module per concern.

mod checkpoint_compat;
mod cli_conventions;
mod data_reader;
mod eval_cli;
mod eval_parts;
mod eval_report;
mod lead_in;
mod lite_imagenet;
mod style_views;
mod summarize;
mod train_classes;
mod train_fine_tuned;
mod train_from_images;
mod train_frozen_checkpoint;
mod train_heads;
mod train_learning;
mod train_scratch;
mod train_set_size;
mod train_stability;
mod view_damping;
