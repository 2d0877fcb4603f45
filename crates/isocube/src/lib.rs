//! isocube: scalar fields to triangle meshes that are correct, good and fast.
pub mod cube;
