//! Spatial discretizations as operators.

pub mod standard;
pub mod wls;
