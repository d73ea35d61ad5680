//! Adaptive configurations that change which scheme (or grid) updates each node.

pub mod hybrid;
pub mod motion;
