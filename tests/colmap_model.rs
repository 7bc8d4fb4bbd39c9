//! COLMAP model reading/writing round trips and corrupt-input errors.
mod common;
