//! Pure-Rust geometry core of kinmo.
//!
//! Nothing here depends on Python: `cargo test -p kinmo-geometry` needs no interpreter.
//! The Python bindings live in the `kinmo-py` crate (`kinmo._core`).
//!
//! Conventions: points are `nalgebra::Point3<f64>`, meshes are triangle soups with
//! `u32` vertex indices, PartNet objects are y-up.

pub mod contact;
pub mod decompose;
pub mod error;
pub mod hull;
pub mod interaction;
pub mod mesh;
pub mod motion;
pub mod obb;
pub mod pointnet;
pub mod proximity;
pub mod sampling;
pub mod sweep;
#[cfg(test)]
mod test_meshes;

pub use error::{GeometryError, Result};
