//! The one error type of the geometry core.

use thiserror::Error;

/// Every way a geometry function can refuse its input.
///
/// The Python bindings map each variant to a Python exception in one place
/// (`kinmo-py/src/errors.rs`): `Io` to `OSError`, everything else to `ValueError`.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GeometryError {
    /// An array had the wrong shape; `what` names the argument.
    #[error("{what}: expected shape {expected}, got {got}")]
    Shape {
        /// Argument name.
        what: String,
        /// Expected shape, e.g. `(N, 3)`.
        expected: String,
        /// Actual shape.
        got: String,
    },
    /// A coordinate or parameter was NaN or infinite.
    #[error("{what}: non-finite value at index {index}")]
    NonFinite {
        /// Argument name.
        what: String,
        /// Flat index of the first offending value.
        index: usize,
    },
    /// A face referenced a vertex that does not exist.
    #[error(
        "{what}: face {face} references vertex {vertex}, but there are only {n_vertices} vertices"
    )]
    IndexOutOfRange {
        /// Argument name.
        what: String,
        /// Face number.
        face: usize,
        /// Offending vertex index.
        vertex: i64,
        /// Number of vertices.
        n_vertices: usize,
    },
    /// An input that must not be empty was empty, or had zero area / length.
    #[error("{0}")]
    Degenerate(String),
    /// Any other invalid argument.
    #[error("{0}")]
    Invalid(String),
    /// A file was read but its content is invalid (e.g. a malformed OBJ); the message names
    /// the file. Maps to `ValueError`.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// A file could not be opened or read; the message names the file. Maps to `OSError`.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

/// Result alias of the geometry core.
pub type Result<T> = std::result::Result<T, GeometryError>;
