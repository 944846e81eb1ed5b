//! Helpers for the cross-program tests in this folder.
