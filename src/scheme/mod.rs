//! Spatial discretizations as operators.

pub mod standard;
