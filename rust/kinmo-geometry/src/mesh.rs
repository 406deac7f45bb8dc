//! Triangle meshes and Wavefront OBJ loading.
//!
//! [`TriMesh`] is the mesh type of the whole core: a vertex array and `u32` triangle
//! indices, validated on construction (finite vertices, indices in range). [`load_obj`]
//! reads one OBJ file with the `tobj` crate (triangulated, all objects/groups merged,
//! materials ignored); [`load_objs`] reads many files in parallel.

use std::path::Path;

use nalgebra::Point3;
use rayon::prelude::*;

use crate::error::{GeometryError, Result};

/// A triangle mesh: vertices and zero-based `u32` vertex indices of each triangle.
///
/// Built through [`TriMesh::new`], which guarantees that every vertex is finite and every
/// index is in range, so the methods below never index out of bounds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    vertices: Vec<Point3<f64>>,
    faces: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Build a mesh, checking that vertices are finite and faces index existing vertices.
    ///
    /// `what` names the mesh in error messages (an argument name or a file path).
    ///
    /// # Errors
    /// [`GeometryError::NonFinite`] (flat index into the `(V, 3)` coordinates) or
    /// [`GeometryError::IndexOutOfRange`].
    pub fn new(vertices: Vec<Point3<f64>>, faces: Vec<[u32; 3]>, what: &str) -> Result<Self> {
        check_finite(&vertices, what)?;
        let n = vertices.len();
        for (fi, f) in faces.iter().enumerate() {
            for &v in f {
                if v as usize >= n {
                    return Err(GeometryError::IndexOutOfRange {
                        what: what.to_string(),
                        face: fi,
                        vertex: i64::from(v),
                        n_vertices: n,
                    });
                }
            }
        }
        Ok(Self { vertices, faces })
    }

    /// The vertices, `(V, 3)`.
    pub fn vertices(&self) -> &[Point3<f64>] {
        &self.vertices
    }

    /// The triangles, `(F, 3)` zero-based vertex indices.
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of triangles.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    /// Split into `(vertices, faces)`.
    pub fn into_parts(self) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        (self.vertices, self.faces)
    }

    /// Corners of triangle `f`.
    ///
    /// # Panics
    /// If `f >= self.n_faces()` (an internal indexing error, never user data).
    pub fn triangle(&self, f: usize) -> [Point3<f64>; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Area of each triangle (`|ab x ac| / 2`, squared input units).
    pub fn face_areas(&self) -> Vec<f64> {
        (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.triangle(f);
                triangle_area(&a, &b, &c)
            })
            .collect()
    }

    /// Total surface area (sum of the triangle areas).
    pub fn area(&self) -> f64 {
        self.face_areas().iter().sum()
    }

    /// Axis-aligned bounds `(min, max)` of the vertices, `None` for a mesh without vertices.
    ///
    /// Unreferenced vertices count too (as in trimesh with `process=False`).
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let first = *self.vertices.first()?;
        Some(self.vertices.iter().fold((first, first), |(lo, hi), p| {
            (lo.inf(p), hi.sup(p))
        }))
    }
}

/// Area of the triangle `abc`.
pub fn triangle_area(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Check that all coordinates are finite.
///
/// # Errors
/// [`GeometryError::NonFinite`] with the flat index (into the `(N, 3)` array) of the first
/// NaN or infinite coordinate.
pub fn check_finite(points: &[Point3<f64>], what: &str) -> Result<()> {
    for (i, p) in points.iter().enumerate() {
        for (k, x) in p.coords.iter().enumerate() {
            if !x.is_finite() {
                return Err(GeometryError::NonFinite {
                    what: what.to_string(),
                    index: 3 * i + k,
                });
            }
        }
    }
    Ok(())
}

/// Read a Wavefront OBJ file as one triangle mesh.
///
/// Polygons are triangulated (fan), all objects and groups of the file are merged into one
/// vertex/face list (face indices are offset accordingly), and materials, normals and
/// texture coordinates are ignored: a missing or broken `.mtl` file is not an error.
/// Vertices are in the file's frame and units.
///
/// # Errors
/// [`GeometryError::Io`] naming the file when it is missing, unreadable or does not parse,
/// has a non-finite vertex, or a face index out of range.
pub fn load_obj(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let io = |message: String| GeometryError::Io {
        path: name.clone(),
        message,
    };
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let file = std::fs::File::open(path).map_err(|e| io(format!("cannot open: {e}")))?;
    let mut reader = std::io::BufReader::with_capacity(1 << 16, file);
    // Materials are never read: a missing or broken `.mtl` cannot fail the load.
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &opts, |_| {
        Ok((Vec::new(), std::collections::HashMap::new()))
    })
    .map_err(|e| io(obj_error(&e)))?;

    let n_vertices: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    let n_faces: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let mut vertices = Vec::with_capacity(n_vertices);
    let mut faces = Vec::with_capacity(n_faces);
    for model in &models {
        let mesh = &model.mesh;
        let offset = vertices.len();
        let n_here = mesh.positions.len() / 3;
        vertices.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|c| Point3::new(c[0], c[1], c[2])),
        );
        for (k, tri) in mesh.indices.chunks_exact(3).enumerate() {
            let mut face = [0u32; 3];
            for (slot, &i) in face.iter_mut().zip(tri) {
                let i = i as usize;
                if i >= n_here {
                    return Err(io(format!(
                        "face {} of object '{}' references vertex {} of {}",
                        faces.len() + k,
                        model.name,
                        i,
                        n_here
                    )));
                }
                *slot = u32::try_from(offset + i)
                    .map_err(|_| io("more than 2^32 vertices".to_string()))?;
            }
            faces.push(face);
        }
    }
    TriMesh::new(vertices, faces, &name).map_err(|e| match e {
        GeometryError::NonFinite { index, .. } => io(format!(
            "non-finite coordinate in vertex {} (1-based line order of 'v' records: {})",
            index / 3,
            index / 3 + 1
        )),
        other => io(other.to_string()),
    })
}

/// Read many OBJ files in parallel (rayon); same contract as [`load_obj`].
///
/// The result is in the order of `paths`.
///
/// # Errors
/// The error of the first failing file in `paths` order.
pub fn load_objs<P: AsRef<Path> + Sync>(paths: &[P]) -> Result<Vec<TriMesh>> {
    // Collect every result first, so the reported error is the first in input order,
    // whatever the thread scheduling.
    let results: Vec<Result<TriMesh>> = paths.par_iter().map(load_obj).collect();
    results.into_iter().collect()
}

/// A readable message for a `tobj` error.
fn obj_error(e: &tobj::LoadError) -> String {
    use tobj::LoadError as E;
    match e {
        E::OpenFileFailed => "cannot open the file".to_string(),
        E::ReadError => "read error (not a text file?)".to_string(),
        E::UnrecognizedCharacter => "malformed OBJ: unrecognized character".to_string(),
        E::PositionParseError => "malformed OBJ: cannot parse a vertex position".to_string(),
        E::NormalParseError => "malformed OBJ: cannot parse a vertex normal".to_string(),
        E::TexcoordParseError => {
            "malformed OBJ: cannot parse a texture coordinate".to_string()
        }
        E::FaceParseError => "malformed OBJ: cannot parse a face".to_string(),
        E::FaceVertexOutOfBounds => "malformed OBJ: face vertex index out of range".to_string(),
        E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds => {
            "malformed OBJ: face attribute index out of range".to_string()
        }
        other => format!("malformed OBJ: {other}"),
    }
}
