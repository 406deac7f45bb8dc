//! Batched candidate rigid motions about / along axes (revolute, prismatic, screw).
//!
//! Candidate `c` rotates by `angles[c]` radians about the line through `origins[c]` with
//! direction `directions[c]` (right-hand rule), then translates by `translations[c]` along
//! the unit direction:
//!
//! `x' = R (x - o) + o + t u`, with `R = cos θ I + sin θ [u]x + (1 - cos θ) u uᵀ`
//! (Rodrigues' rotation formula) and `u = d / |d|`.
//!
//! Revolute joints have `t = 0`, prismatic joints `θ = 0`. Batches run in parallel over
//! candidates (and over blocks of points inside a candidate) and write straight into one
//! row-major output buffer.

use nalgebra::{Matrix3, Matrix4, Point3, Unit, Vector3};
use rayon::prelude::*;

use crate::error::{GeometryError, Result};

/// Points per parallel work item inside one candidate of [`apply_motions_into`].
const POINT_BLOCK: usize = 16_384;

/// One rigid motion `x -> R x + t` (rotation matrix and translation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Rotation part.
    pub rotation: Matrix3<f64>,
    /// Translation part.
    pub translation: Vector3<f64>,
}

impl Motion {
    /// The motion of rotating by `angle` radians about the line `(origin, axis)` (right-hand
    /// rule), then translating by `translation` along `axis`.
    pub fn about_axis(
        origin: &Point3<f64>,
        axis: &Unit<Vector3<f64>>,
        angle: f64,
        translation: f64,
    ) -> Self {
        let u = axis.as_ref();
        let (s, c) = angle.sin_cos();
        let k = Matrix3::new(0.0, -u.z, u.y, u.z, 0.0, -u.x, -u.y, u.x, 0.0);
        let rotation = Matrix3::identity() * c + k * s + (u * u.transpose()) * (1.0 - c);
        let o = origin.coords;
        let t = o - rotation * o + u * translation;
        Self {
            rotation,
            translation: t,
        }
    }

    /// Apply to a point.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * p.coords + self.translation)
    }

    /// Homogeneous `4 x 4` matrix acting on column vectors.
    pub fn to_homogeneous(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

/// Validate a batch of C candidates and build their motions.
///
/// # Errors
/// [`GeometryError::Shape`] when the four inputs differ in length;
/// [`GeometryError::NonFinite`] for a NaN/inf value (naming the argument);
/// [`GeometryError::Degenerate`] for a zero-length direction (naming the candidate).
pub fn motions(
    origins: &[Point3<f64>],
    directions: &[Vector3<f64>],
    angles: &[f64],
    translations: &[f64],
) -> Result<Vec<Motion>> {
    let c = origins.len();
    for (what, len, expected) in [
        ("directions", directions.len(), "(C, 3)"),
        ("angles", angles.len(), "(C,)"),
        ("translations", translations.len(), "(C,)"),
    ] {
        if len != c {
            return Err(GeometryError::Shape {
                what: what.to_string(),
                expected: format!("{expected} with C = {c} (the number of origins)"),
                got: if expected == "(C,)" {
                    format!("({len},)")
                } else {
                    format!("({len}, 3)")
                },
            });
        }
    }
    finite(
        "origins",
        origins.iter().flat_map(|p| p.coords.iter().copied()),
    )?;
    finite(
        "directions",
        directions.iter().flat_map(|d| d.iter().copied()),
    )?;
    finite("angles", angles.iter().copied())?;
    finite("translations", translations.iter().copied())?;
    (0..c)
        .map(|i| {
            let Some(axis) = unit_direction(&directions[i]) else {
                return Err(GeometryError::Degenerate(format!(
                    "directions[{i}]: zero-length axis direction of candidate {i}"
                )));
            };
            Ok(Motion::about_axis(
                &origins[i],
                &axis,
                angles[i],
                translations[i],
            ))
        })
        .collect()
}

/// The unit vector along finite `d`, scale-robust: `d` is first divided by its largest
/// magnitude, so neither `(1e300, 1e300, 0)` (whose squared norm overflows) nor
/// `(1e-300, 0, 0)` (whose squared norm underflows) is taken for a zero vector. `None` only
/// for the zero vector (or a non-finite one).
pub fn unit_direction(d: &Vector3<f64>) -> Option<Unit<Vector3<f64>>> {
    let m = d.amax();
    if !(m > 0.0 && m.is_finite()) {
        return None;
    }
    let s = d / m;
    Some(Unit::new_unchecked(s / s.norm()))
}

/// Homogeneous matrices of C candidates as a flat row-major `(C, 4, 4)` buffer.
///
/// # Errors
/// As [`motions`].
pub fn motion_transforms(
    origins: &[Point3<f64>],
    directions: &[Vector3<f64>],
    angles: &[f64],
    translations: &[f64],
) -> Result<Vec<f64>> {
    let ms = motions(origins, directions, angles, translations)?;
    let mut out = Vec::with_capacity(16 * ms.len());
    for m in &ms {
        let h = m.to_homogeneous();
        for r in 0..4 {
            for k in 0..4 {
                out.push(h[(r, k)]);
            }
        }
    }
    Ok(out)
}

/// Apply every motion to every point, writing a row-major `(C, N, 3)` buffer into `out`.
///
/// Parallel over candidates and blocks of points.
///
/// # Errors
/// [`GeometryError::Shape`] when `out.len() != 3 * motions.len() * points.len()`.
pub fn apply_motions_into(
    motions: &[Motion],
    points: &[Point3<f64>],
    out: &mut [f64],
) -> Result<()> {
    let n = points.len();
    if out.len() != 3 * n * motions.len() {
        return Err(GeometryError::Shape {
            what: "out".to_string(),
            expected: format!("({}, {n}, 3)", motions.len()),
            got: format!("({},)", out.len()),
        });
    }
    if n == 0 {
        return Ok(());
    }
    out.par_chunks_mut(3 * n)
        .zip(motions.par_iter())
        .for_each(|(cand, m)| {
            cand.par_chunks_mut(3 * POINT_BLOCK)
                .zip(points.par_chunks(POINT_BLOCK))
                .for_each(|(dst, src)| transform_block(m, src, dst));
        });
    Ok(())
}

/// Apply C candidate motions to N points: a row-major `(C, N, 3)` buffer.
///
/// # Errors
/// As [`motions`].
pub fn apply_motions(
    points: &[Point3<f64>],
    origins: &[Point3<f64>],
    directions: &[Vector3<f64>],
    angles: &[f64],
    translations: &[f64],
) -> Result<Vec<f64>> {
    let ms = motions(origins, directions, angles, translations)?;
    let mut out = vec![0.0; 3 * ms.len() * points.len()];
    apply_motions_into(&ms, points, &mut out)?;
    Ok(out)
}

/// Error naming `what` and the flat index of the first NaN/inf of `values`.
fn finite(what: &str, mut values: impl Iterator<Item = f64>) -> Result<()> {
    match values.position(|x| !x.is_finite()) {
        Some(index) => Err(GeometryError::NonFinite {
            what: what.to_string(),
            index,
        }),
        None => Ok(()),
    }
}

/// `dst[i] = R src[i] + t` for one block (scalar code the compiler unrolls).
#[inline]
fn transform_block(m: &Motion, src: &[Point3<f64>], dst: &mut [f64]) {
    let r = &m.rotation;
    let (r00, r01, r02) = (r[(0, 0)], r[(0, 1)], r[(0, 2)]);
    let (r10, r11, r12) = (r[(1, 0)], r[(1, 1)], r[(1, 2)]);
    let (r20, r21, r22) = (r[(2, 0)], r[(2, 1)], r[(2, 2)]);
    let (tx, ty, tz) = (m.translation.x, m.translation.y, m.translation.z);
    for (p, q) in src.iter().zip(dst.chunks_exact_mut(3)) {
        let (x, y, z) = (p.x, p.y, p.z);
        q[0] = r00 * x + r01 * y + r02 * z + tx;
        q[1] = r10 * x + r11 * y + r12 * z + ty;
        q[2] = r20 * x + r21 * y + r22 * z + tz;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    fn close(a: &Point3<f64>, b: &Point3<f64>) -> bool {
        (a - b).norm() < 1e-12
    }

    #[test]
    fn quarter_turn_about_offset_z_axis() {
        // Rotate (2,1,0) by +90 deg about the z-parallel line through (1,1,0): -> (1,2,0).
        let ms = motions(
            &[p(1.0, 1.0, 0.0)],
            &[Vector3::new(0.0, 0.0, 5.0)],
            &[FRAC_PI_2],
            &[0.0],
        )
        .expect("valid");
        assert!(close(&ms[0].apply(&p(2.0, 1.0, 0.0)), &p(1.0, 2.0, 0.0)));
        // Points on the axis do not move.
        assert!(close(&ms[0].apply(&p(1.0, 1.0, 7.0)), &p(1.0, 1.0, 7.0)));
    }

    #[test]
    fn right_hand_rule_about_x() {
        // +90 deg about +x maps +y to +z.
        let ms = motions(&[p(0.0, 0.0, 0.0)], &[Vector3::x()], &[FRAC_PI_2], &[0.0]).expect("ok");
        assert!(close(&ms[0].apply(&p(0.0, 1.0, 0.0)), &p(0.0, 0.0, 1.0)));
    }

    #[test]
    fn translation_along_unit_direction() {
        let ms = motions(
            &[p(3.0, 3.0, 3.0)],
            &[Vector3::new(0.0, 2.0, 0.0)],
            &[0.0],
            &[0.5],
        )
        .expect("ok");
        assert!(close(&ms[0].apply(&p(1.0, 2.0, 3.0)), &p(1.0, 2.5, 3.0)));
    }

    #[test]
    fn screw_is_rotation_then_translation() {
        let d = Vector3::new(1.0, 1.0, 1.0);
        let o = p(0.5, -1.0, 2.0);
        let screw = motions(&[o], &[d], &[0.7], &[0.3]).expect("ok")[0];
        let rot = motions(&[o], &[d], &[0.7], &[0.0]).expect("ok")[0];
        let q = p(-1.0, 0.25, 4.0);
        let expected = rot.apply(&q) + d.normalize() * 0.3;
        assert!(close(&screw.apply(&q), &expected));
    }

    #[test]
    fn full_turn_is_identity_and_half_turns_compose() {
        let o = [p(0.3, -0.2, 1.0)];
        let d = [Vector3::new(0.2, -0.9, 0.4)];
        let full = motions(&o, &d, &[TAU], &[0.0]).expect("ok")[0];
        assert!((full.to_homogeneous() - Matrix4::identity()).abs().max() < 1e-14);
        let half = motions(&o, &d, &[PI], &[0.0]).expect("ok")[0];
        let q = p(1.0, 2.0, 3.0);
        assert!(close(&half.apply(&half.apply(&q)), &q));
        // Rotation part is orthonormal with determinant 1.
        let r = half.rotation;
        assert!((r.transpose() * r - Matrix3::identity()).abs().max() < 1e-14);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
    }

    #[test]
    fn matrices_agree_with_apply() {
        let o = [p(0.0, 1.0, 0.0), p(1.0, 2.0, 3.0), p(-1.0, 0.0, 0.5)];
        let d = [
            Vector3::x(),
            Vector3::new(1.0, 2.0, 2.0),
            Vector3::new(0.0, -3.0, 0.0),
        ];
        let a = [0.3, -1.2, 2.0];
        let t = [0.0, 0.1, -0.4];
        let pts: Vec<Point3<f64>> = (0..40_000)
            .map(|i| {
                let f = i as f64;
                p(f.sin(), (0.3 * f).cos(), 0.001 * f)
            })
            .collect();
        let mats = motion_transforms(&o, &d, &a, &t).expect("ok");
        let out = apply_motions(&pts, &o, &d, &a, &t).expect("ok");
        assert_eq!(out.len(), 3 * 3 * pts.len());
        for c in 0..3 {
            let m = Matrix4::from_row_slice(&mats[16 * c..16 * (c + 1)]);
            assert_eq!(
                m.row(3).transpose(),
                nalgebra::Vector4::new(0.0, 0.0, 0.0, 1.0)
            );
            for (i, q) in pts.iter().enumerate().step_by(997) {
                let h = m * q.to_homogeneous();
                let k = 3 * (c * pts.len() + i);
                let got = p(out[k], out[k + 1], out[k + 2]);
                assert!(
                    close(&got, &Point3::from(h.xyz())),
                    "candidate {c}, point {i}"
                );
            }
        }
    }

    #[test]
    fn errors() {
        let o = [p(0.0, 0.0, 0.0), p(0.0, 0.0, 0.0)];
        let d = [Vector3::x(), Vector3::zeros()];
        match motions(&o, &d, &[0.0, 0.0], &[0.0, 0.0]) {
            Err(GeometryError::Degenerate(m)) => assert!(m.contains("candidate 1"), "{m}"),
            other => panic!("expected a zero-length error, got {other:?}"),
        }
        assert!(matches!(
            motions(&o, &d, &[0.0], &[0.0, 0.0]),
            Err(GeometryError::Shape { .. })
        ));
        assert!(matches!(
            motions(&o[..1], &d[..1], &[f64::NAN], &[0.0]),
            Err(GeometryError::NonFinite { .. })
        ));
        let ms = motions(&o[..1], &d[..1], &[0.0], &[0.0]).expect("ok");
        let mut out = vec![0.0; 5];
        assert!(apply_motions_into(&ms, &[p(0.0, 0.0, 0.0)], &mut out).is_err());
    }

    #[test]
    fn empty_batches() {
        assert!(motion_transforms(&[], &[], &[], &[])
            .expect("ok")
            .is_empty());
        let out = apply_motions(&[], &[p(0.0, 0.0, 0.0)], &[Vector3::z()], &[1.0], &[0.0]);
        assert!(out.expect("ok").is_empty());
    }

    #[test]
    fn extreme_directions_are_unit_not_zero_length() {
        for d in [
            Vector3::new(1e300, 1e300, 0.0),
            Vector3::new(-1e-300, 0.0, 0.0),
            Vector3::new(f64::MAX, f64::MAX, f64::MAX),
            Vector3::new(5e-324, 0.0, 5e-324),
        ] {
            let u = unit_direction(&d).expect("non-zero direction");
            assert!((u.norm() - 1.0).abs() < 1e-15, "{d}: {}", u.norm());
            assert!((u.dot(&d.map(f64::signum)) > 0.0), "{d}");
        }
        assert!(unit_direction(&Vector3::zeros()).is_none());
        let m = motions(
            &[Point3::origin()],
            &[Vector3::new(1e300, 1e300, 0.0)],
            &[0.0],
            &[1.0],
        )
        .expect("a valid direction");
        assert_eq!(m.len(), 1);
    }
}
