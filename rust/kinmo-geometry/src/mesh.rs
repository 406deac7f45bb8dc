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
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }
}

/// Area of the triangle `abc`.
pub fn triangle_area(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Coordinates smaller than this in magnitude are flushed to zero before parry builds a
/// BVH ([`flush_tiny`]).
///
/// parry's binned BVH build divides by the extent of the leaves' centres; an extent in the
/// subnormal range (all triangles within ~1e-300 of each other) overflows that division
/// and panics inside parry. After flushing, any non-zero difference of two coordinates is
/// at least ~1e-166 (the spacing of f64 values near 1e-150), so the division stays finite.
/// 1e-150 mesh units is far below any geometry kinmo handles (meshes are in metres or unit
/// boxes), and every caller applies it after scaling to unit magnitude where it scales.
pub const TINY_COORDINATE: f64 = 1e-150;

/// `p` with every coordinate of magnitude below [`TINY_COORDINATE`] set to zero.
pub fn flush_tiny(p: &Point3<f64>) -> Point3<f64> {
    p.map(|x| if x.abs() < TINY_COORDINATE { 0.0 } else { x })
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
/// [`GeometryError::Io`] naming the file when it is missing, unreadable, not a regular
/// file (a directory, a device such as `/dev/zero`, a FIFO) or larger than
/// [`MAX_OBJ_BYTES`] (see [`load_obj_bounded`] for another limit); [`GeometryError::Parse`]
/// naming the file when it does not parse, is
/// a text file without any vertex whose lines are no OBJ statements, has a non-finite
/// vertex or one beyond the float32 range, or a face index out of range. A leading UTF-8
/// byte order mark is skipped; an empty or comment-only file is an empty mesh.
pub fn load_obj(path: impl AsRef<Path>) -> Result<TriMesh> {
    load_obj_bounded(path, MAX_OBJ_BYTES)
}

/// [`load_obj`] with `max_bytes` as the largest file read (kinmo's configurable
/// `file_bytes` limit, `kinmo --limit file_bytes=N`); larger files are refused before
/// reading.
///
/// # Errors
/// As [`load_obj`], the size limit being `max_bytes`.
pub fn load_obj_bounded(path: impl AsRef<Path>, max_bytes: u64) -> Result<TriMesh> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let io = |message: String| GeometryError::Io {
        path: name.clone(),
        message,
    };
    let parse = |message: String| GeometryError::Parse {
        path: name.clone(),
        message,
    };
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let bytes = read_bounded(path, max_bytes).map_err(io)?;
    if bytes.contains(&0) {
        return Err(parse(
            "binary data (NUL bytes): not a text OBJ file".to_string(),
        ));
    }
    // Invalid UTF-8 (e.g. Latin-1 comments or group names) is replaced, not fatal. The
    // strict check first: it is several times faster than the lossy decoder on valid text.
    let text = match std::str::from_utf8(&bytes) {
        Ok(s) => std::borrow::Cow::Borrowed(s),
        Err(_) => String::from_utf8_lossy(&bytes),
    };
    // A UTF-8 byte order mark would hide the first statement.
    let text = text.strip_prefix('\u{FEFF}').unwrap_or(&text);
    // Materials are never read: a missing or broken `.mtl` cannot fail the load.
    let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |_| {
        Ok((Vec::new(), Default::default()))
    })
    .map_err(|e| parse(obj_error(&e)))?;

    let n_vertices: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    if n_vertices == 0 {
        if let Some((line, word)) = first_foreign_statement(text) {
            return Err(parse(format!(
                "not an OBJ file: no vertex, and line {line} starts with '{word}', \
                 which is no OBJ statement"
            )));
        }
    }
    let beyond_f32 = models
        .iter()
        .flat_map(|m| m.mesh.positions.iter())
        .position(|x| x.is_finite() && x.abs() > f64::from(f32::MAX));
    if let Some(index) = beyond_f32 {
        return Err(parse(format!(
            "vertex {} (counted in object order) has a coordinate beyond the float32 range \
             (|x| > 3.4e38), which kinmo's float32 caches cannot hold",
            index / 3
        )));
    }
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
        for tri in mesh.indices.chunks_exact(3) {
            let mut face = [0u32; 3];
            for (slot, &i) in face.iter_mut().zip(tri) {
                let i = i as usize;
                if i >= n_here {
                    return Err(parse(format!(
                        "face {} of object '{}' references vertex {} of {}",
                        faces.len(),
                        model.name,
                        i,
                        n_here
                    )));
                }
                *slot = u32::try_from(offset + i)
                    .map_err(|_| parse("more than 2^32 vertices".to_string()))?;
            }
            faces.push(face);
        }
    }
    TriMesh::new(vertices, faces, &name).map_err(|e| match e {
        GeometryError::NonFinite { index, .. } => parse(format!(
            "vertex {} (counted in object order) has a non-finite coordinate (NaN or inf)",
            index / 3
        )),
        other => parse(other.to_string()),
    })
}

/// Default of the largest OBJ file [`load_obj`] reads (4 GiB, the default of kinmo's
/// `file_bytes` limit, which Python passes to [`load_obj_bounded`]); larger files are
/// refused before reading.
pub const MAX_OBJ_BYTES: u64 = 1 << 32;

/// Statement keywords of the OBJ format (Wavefront, *Object Files*, Appendix B1 of the
/// Advanced Visualizer manual), vertex data, elements, grouping, display and free-form.
const OBJ_KEYWORDS: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "fo",
    "l",
    "p",
    "o",
    "g",
    "s",
    "mg",
    "mtllib",
    "usemtl",
    "maplib",
    "usemap",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "call",
    "csh",
];

/// The first non-blank, non-comment line whose first word is no OBJ keyword:
/// `(1-based line number, word)` (the word cut to 20 characters).
fn first_foreign_statement(text: &str) -> Option<(usize, String)> {
    text.lines().enumerate().find_map(|(i, line)| {
        let word = line.split_whitespace().next()?;
        if word.starts_with('#') || OBJ_KEYWORDS.contains(&word) {
            return None;
        }
        Some((i + 1, word.chars().take(20).collect()))
    })
}

/// Read a regular file of at most `limit` bytes; the error message (without the path)
/// says why not: missing, not a regular file (a directory, `/dev/zero`, a FIFO), too
/// large, or unreadable.
fn read_bounded(path: &Path, limit: u64) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read: {e}"))?;
    if meta.is_dir() {
        return Err("cannot read: is a directory".to_string());
    }
    if !meta.is_file() {
        return Err("cannot read: not a regular file".to_string());
    }
    if meta.len() > limit {
        return Err(format!(
            "cannot read: file too large ({} bytes, the limit is {limit})",
            meta.len()
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut bytes = Vec::new();
    // `take`: a file that grows while being read still stops at the limit.
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!(
            "cannot read: file too large (the limit is {limit} bytes)"
        ));
    }
    Ok(bytes)
}

/// Read many OBJ files in parallel (rayon); same contract as [`load_obj`].
///
/// The result is in the order of `paths`.
///
/// # Errors
/// The error of the first failing file in `paths` order.
pub fn load_objs<P: AsRef<Path> + Sync>(paths: &[P]) -> Result<Vec<TriMesh>> {
    load_objs_bounded(paths, MAX_OBJ_BYTES)
}

/// [`load_objs`] with `max_bytes` as the largest file read ([`load_obj_bounded`]).
///
/// # Errors
/// As [`load_objs`].
pub fn load_objs_bounded<P: AsRef<Path> + Sync>(
    paths: &[P],
    max_bytes: u64,
) -> Result<Vec<TriMesh>> {
    // Collect every result first, so the reported error is the first in input order,
    // whatever the thread scheduling.
    let results: Vec<Result<TriMesh>> = paths
        .par_iter()
        .map(|p| load_obj_bounded(p, max_bytes))
        .collect();
    results.into_iter().collect()
}

/// A readable message for a `tobj` error.
fn obj_error(e: &tobj::LoadError) -> String {
    use tobj::LoadError as E;
    match e {
        E::OpenFileFailed => "cannot open the file".to_string(),
        E::ReadError => "read error".to_string(),
        E::UnrecognizedCharacter => "malformed OBJ: unrecognized character".to_string(),
        E::PositionParseError => "malformed OBJ: cannot parse a vertex position".to_string(),
        E::NormalParseError => "malformed OBJ: cannot parse a vertex normal".to_string(),
        E::TexcoordParseError => "malformed OBJ: cannot parse a texture coordinate".to_string(),
        E::FaceParseError => "malformed OBJ: cannot parse a face".to_string(),
        E::FaceVertexOutOfBounds => "malformed OBJ: face vertex index out of range".to_string(),
        E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds => {
            "malformed OBJ: face attribute index out of range".to_string()
        }
        other => format!("malformed OBJ: {other}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A test file, removed when dropped.
    struct TempObj(PathBuf);

    impl std::ops::Deref for TempObj {
        type Target = Path;
        fn deref(&self) -> &Path {
            &self.0
        }
    }

    impl AsRef<Path> for TempObj {
        fn as_ref(&self) -> &Path {
            &self.0
        }
    }

    impl Drop for TempObj {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    /// Write `text` to a fresh file in the temp folder (names are unique per test).
    fn obj_file(name: &str, text: impl AsRef<[u8]>) -> TempObj {
        let dir = std::env::temp_dir().join(format!("kinmo-mesh-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write obj");
        TempObj(path)
    }

    #[test]
    fn quads_triangulated_objects_merged_materials_ignored() {
        let path = obj_file(
            "two_objects.obj",
            "mtllib missing.mtl\no a\nusemtl nothing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
             f 1 2 3 4\no b\nv 0 0 2\nv 2 0 2\nv 0 2 2\nf -3 -2 -1\n",
        );
        let m = load_obj(&path).expect("loads");
        assert_eq!(m.n_vertices(), 7);
        assert_eq!(m.n_faces(), 3);
        // Unit square (area 1) + right triangle of legs 2 (area 2).
        assert!((m.area() - 3.0).abs() < 1e-15);
        // The second object's face indexes the merged vertex list.
        assert!(m.faces()[2].iter().all(|&i| i >= 4));
        let (lo, hi) = m.bounds().expect("non-empty");
        assert_eq!(
            (lo, hi),
            (Point3::new(0.0, 0.0, 0.0), Point3::new(2.0, 2.0, 2.0))
        );
    }

    #[test]
    fn the_size_limit_is_the_callers() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let path = obj_file("bounded.obj", text);
        let n = text.len() as u64;
        assert_eq!(
            load_obj_bounded(&path, n).expect("at the limit").n_faces(),
            1
        );
        match load_obj_bounded(&path, n - 1) {
            Err(GeometryError::Io { path: p, message }) => {
                assert!(p.ends_with("bounded.obj"));
                assert!(message.contains("too large") && message.contains(&format!("{}", n - 1)));
            }
            other => panic!("expected an Io error, got {other:?}"),
        }
        let all = load_objs_bounded(&[&path, &path], n - 1);
        assert!(matches!(all, Err(GeometryError::Io { .. })));
        assert_eq!(
            load_objs_bounded(&[&path, &path], n).expect("both").len(),
            2
        );
    }

    #[test]
    fn io_errors_name_the_file() {
        let missing = std::env::temp_dir().join("kinmo-definitely-missing.obj");
        match load_obj(&missing) {
            Err(GeometryError::Io { path, .. }) => {
                assert!(path.contains("kinmo-definitely-missing"))
            }
            other => panic!("expected Io, got {other:?}"),
        }
        for (name, text) in [
            ("bad_vertex.obj", "v 0 zero 0\nf 1 1 1\n"),
            ("bad_face.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
            ("nan_vertex.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
            ("inf_vertex.obj", "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n"),
            ("zero_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
            ("binary.obj", "v 0 0 0\n\0\x01\x02\n"),
            (
                "readme.obj",
                "This is a README, not a mesh.\nSee the docs.\n",
            ),
            ("json.obj", "{\"v\": [1, 2, 3]}\n"),
            ("huge_vertex.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n"),
            (
                "very_huge_vertex.obj",
                "v 0 0 0\nv 1 0 0\nv 0 -1e200 0\nf 1 2 3\n",
            ),
        ] {
            let path = obj_file(name, text);
            match load_obj(&path) {
                Err(GeometryError::Parse { path, message }) => {
                    assert!(path.contains(name), "{message}")
                }
                other => panic!("{name}: expected Parse, got {other:?}"),
            }
        }
    }

    #[test]
    fn bom_empty_and_special_files() {
        let bom = obj_file("bom.obj", "\u{FEFF}v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let m = load_obj(&bom).expect("a BOM is skipped");
        assert_eq!((m.n_vertices(), m.n_faces()), (3, 1));
        let empty = obj_file("empty.obj", "");
        assert!(load_obj(&empty).expect("empty mesh").is_empty());
        let comments = obj_file("comments.obj", "# exported by hand\n\n# nothing yet\n");
        assert!(load_obj(&comments).expect("empty mesh").is_empty());
        #[cfg(unix)]
        for special in ["/dev/zero", "/dev/null"] {
            match load_obj(special) {
                Err(GeometryError::Io { path, message }) => {
                    assert_eq!(path, special);
                    assert!(message.contains("not a regular file"), "{message}");
                }
                other => panic!("{special}: expected Io, got {other:?}"),
            }
        }
        let big = obj_file("big.obj", "v 0 0 0\n".repeat(10));
        match read_bounded(&big, 16) {
            Err(m) => assert!(m.contains("too large"), "{m}"),
            Ok(_) => panic!("80 bytes read under a 16-byte limit"),
        }
    }

    #[test]
    fn latin1_comments_and_directories() {
        let path = obj_file(
            "latin1.obj",
            b"# caf\xe9\ng chaise_\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        );
        assert_eq!(load_obj(&path).expect("loads").n_faces(), 1);
        let dir = path.parent().expect("has a parent");
        assert!(matches!(load_obj(dir), Err(GeometryError::Io { .. })));
    }

    #[test]
    fn load_objs_keeps_order_and_reports_first_error() {
        let a = obj_file("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let b = obj_file(
            "b.obj",
            "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 2 2 0\nf 1 2 3\nf 2 4 3\n",
        );
        let ms = load_objs(&[&a, &b, &a]).expect("loads");
        assert_eq!(
            ms.iter().map(TriMesh::n_faces).collect::<Vec<_>>(),
            [1, 2, 1]
        );
        let bad = obj_file("c.obj", "v 0 0 0\nf 1 2 3\n");
        match load_objs(&[&a, &bad, &b]) {
            Err(GeometryError::Parse { path, .. }) => assert!(path.ends_with("c.obj")),
            other => panic!("expected Parse, got {other:?}"),
        }
    }

    #[test]
    fn trimesh_new_validates() {
        let v = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
        assert!(matches!(
            TriMesh::new(v.clone(), vec![[0, 1, 2]], "m"),
            Err(GeometryError::IndexOutOfRange {
                face: 0,
                vertex: 2,
                ..
            })
        ));
        let w = vec![Point3::new(0.0, f64::INFINITY, 0.0)];
        assert!(matches!(
            TriMesh::new(w, vec![], "m"),
            Err(GeometryError::NonFinite { index: 1, .. })
        ));
        assert!(TriMesh::new(vec![], vec![], "m")
            .expect("empty ok")
            .bounds()
            .is_none());
    }
}
