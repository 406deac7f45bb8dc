//! Tests of `pointnet.rs` against brute-force definitions, on seeded random clouds.

use super::*;
use proptest::prelude::*;
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

fn cloud(seed: u64, n: usize) -> Vec<Point> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut u = || (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0;
    (0..n).map(|_| [u(), u(), u()]).collect()
}

/// FPS by its definition: the next centre maximises the distance to the chosen set.
fn fps_reference(p: &[Point], m: usize) -> Vec<i64> {
    let mut chosen = vec![0usize];
    while chosen.len() < m {
        let d: Vec<f32> = p
            .iter()
            .map(|q| {
                chosen
                    .iter()
                    .map(|&c| dist2_f32(q, &p[c]))
                    .fold(f32::INFINITY, f32::min)
            })
            .collect();
        let best = d.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        chosen.push(d.iter().position(|&x| x == best).unwrap());
    }
    chosen.into_iter().map(|i| i as i64).collect()
}

fn ball_reference(p: &[Point], c: &Point, r: f64, k: usize) -> Vec<i64> {
    let inside: Vec<i64> = (0..p.len())
        .filter(|&i| dist2_f64(&p[i], c) <= r * r)
        .map(|i| i as i64)
        .take(k)
        .collect();
    let fill = inside.first().copied().unwrap_or_else(|| {
        let mut order: Vec<usize> = (0..p.len()).collect();
        order.sort_by(|&a, &b| dist2_f64(&p[a], c).total_cmp(&dist2_f64(&p[b], c)));
        order[0] as i64
    });
    let mut out = inside;
    out.resize(k, fill);
    out
}

fn knn_reference(p: &[Point], q: &Point, k: usize) -> Vec<i64> {
    let mut order: Vec<usize> = (0..p.len()).collect();
    // stable sort: equal distances keep index order
    order.sort_by(|&a, &b| dist2_f64(&p[a], q).total_cmp(&dist2_f64(&p[b], q)));
    order[..k].iter().map(|&i| i as i64).collect()
}

#[test]
fn fps_matches_its_definition_and_starts_at_zero() {
    for seed in 0..5 {
        let p = cloud(seed, 300);
        let got = farthest_point_sample(&p, 40).unwrap();
        assert_eq!(got[0], 0);
        assert_eq!(got, fps_reference(&p, 40));
        let mut sorted = got.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 40, "distinct points give distinct centres");
    }
}

#[test]
fn fps_on_repeated_points_picks_the_first_of_ties() {
    // points 0..4 repeated: after the 4 distinct ones every distance is 0, so index 0 follows
    let base = cloud(9, 4);
    let p: Vec<Point> = base.iter().chain(base.iter()).copied().collect();
    let got = farthest_point_sample(&p, 6).unwrap();
    assert_eq!(got, fps_reference(&p, 6));
    assert_eq!(&got[4..], &[0, 0]);
}

#[test]
fn batches_equal_their_items() {
    let (b, n, m, k) = (5, 200, 30, 8);
    let clouds: Vec<Vec<Point>> = (0..b).map(|s| cloud(100 + s as u64, n)).collect();
    let flat: Vec<Point> = clouds.iter().flatten().copied().collect();
    let mut idx = vec![0; b * m];
    farthest_point_sample_batch(&flat, b, n, &mut idx).unwrap();
    let centers: Vec<Point> = (0..b)
        .flat_map(|i| {
            let c = &clouds[i];
            idx[i * m..(i + 1) * m]
                .iter()
                .map(|&j| c[j as usize])
                .collect::<Vec<_>>()
        })
        .collect();
    let mut groups = vec![0; b * m * k];
    ball_query_batch(&flat, &centers, b, n, m, 0.3, k, &mut groups).unwrap();
    let mut nn = vec![0; b * n * 3];
    let mut nd = vec![0.0; b * n * 3];
    k_nearest_batch(&centers, &flat, b, m, n, 3, &mut nn, &mut nd).unwrap();
    for i in 0..b {
        let c = &clouds[i];
        let ci = &centers[i * m..(i + 1) * m];
        assert_eq!(
            &idx[i * m..(i + 1) * m],
            &farthest_point_sample(c, m).unwrap()[..]
        );
        assert_eq!(
            &groups[i * m * k..(i + 1) * m * k],
            &ball_query(c, ci, 0.3, k).unwrap()[..]
        );
        let (ki, kd) = k_nearest(ci, c, 3).unwrap();
        assert_eq!(&nn[i * n * 3..(i + 1) * n * 3], &ki[..]);
        assert_eq!(&nd[i * n * 3..(i + 1) * n * 3], &kd[..]);
    }
}

#[test]
fn ball_query_matches_brute_force_and_pads() {
    let p = cloud(3, 400);
    let centers = cloud(4, 50);
    for (r, k) in [(0.05, 4), (0.2, 16), (0.5, 32), (3.0, 8)] {
        let got = ball_query(&p, &centers, r, k).unwrap();
        for (c, row) in centers.iter().zip(got.chunks(k)) {
            assert_eq!(row, &ball_reference(&p, c, r, k)[..]);
        }
    }
    // a centre far from every point gets its nearest point k times
    let far = ball_query(&p, &[[5.0, 5.0, 5.0]], 0.1, 3).unwrap();
    let near = knn_reference(&p, &[5.0, 5.0, 5.0], 1)[0];
    assert_eq!(far, vec![near; 3]);
}

#[test]
fn k_nearest_matches_a_stable_sort() {
    let p = cloud(5, 120);
    let q = cloud(6, 80);
    let (idx, dist) = k_nearest(&p, &q, 3).unwrap();
    for (j, qq) in q.iter().enumerate() {
        let want = knn_reference(&p, qq, 3);
        assert_eq!(&idx[3 * j..3 * j + 3], &want[..]);
        for s in 0..3 {
            let d = dist2_f64(&p[want[s] as usize], qq).sqrt() as f32;
            assert_eq!(dist[3 * j + s], d);
        }
    }
    // a query on a point of the cloud finds it first, at distance exactly 0
    let (i0, d0) = k_nearest(&p, &[p[17]], 3).unwrap();
    assert_eq!((i0[0], d0[0]), (17, 0.0));
    // equal distances keep index order
    let dup = vec![
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
    ];
    assert_eq!(k_nearest(&dup, &[[0.0; 3]], 4).unwrap().0, vec![0, 1, 2, 3]);
}

#[test]
fn searches_are_exact_on_flat_clouds_far_queries_and_tiny_radii() {
    // a flat cloud (z = 0), a line (y = z = 0), queries far outside, radii far below the
    // spacing (cells enlarged) and far above the extent
    let flat: Vec<Point> = cloud(11, 300).iter().map(|p| [p[0], p[1], 0.0]).collect();
    let line: Vec<Point> = cloud(12, 100).iter().map(|p| [p[0], 0.0, 0.0]).collect();
    let far: Vec<Point> = cloud(13, 40)
        .iter()
        .map(|p| [p[0] * 7.0, p[1] * 7.0, p[2] * 7.0])
        .collect();
    for p in [&flat, &line, &cloud(14, 250)] {
        let queries: Vec<Point> = far.iter().chain(p.iter().take(30)).copied().collect();
        for r in [1e-7, 0.01, 0.3, 50.0] {
            let got = ball_query(p, &queries, r, 5).unwrap();
            for (c, row) in queries.iter().zip(got.chunks(5)) {
                assert_eq!(row, &ball_reference(p, c, r, 5)[..]);
            }
        }
        for k in [1, 3, 7] {
            let (got, _) = k_nearest(p, &queries, k).unwrap();
            for (q, row) in queries.iter().zip(got.chunks(k)) {
                assert_eq!(row, &knn_reference(p, q, k)[..]);
            }
        }
    }
}

#[test]
fn bad_arguments_are_errors_naming_them() {
    let p = cloud(1, 10);
    let msg = |e: GeometryError| e.to_string();
    assert!(msg(farthest_point_sample(&p, 11).unwrap_err()).starts_with("m:"));
    assert!(msg(farthest_point_sample(&p, 0).unwrap_err()).starts_with("m:"));
    assert!(matches!(
        farthest_point_sample(&[], 1),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(msg(ball_query(&p, &p, 0.0, 4).unwrap_err()).starts_with("radius:"));
    assert!(msg(ball_query(&p, &p, f64::NAN, 4).unwrap_err()).starts_with("radius:"));
    assert!(msg(ball_query(&p, &p, 0.1, 0).unwrap_err()).starts_with("k:"));
    assert!(msg(k_nearest(&p, &p, 11).unwrap_err()).starts_with("k:"));
    let mut bad = p.clone();
    bad[2][1] = f32::NAN;
    assert_eq!(
        farthest_point_sample(&bad, 3).unwrap_err(),
        GeometryError::NonFinite {
            what: "points".to_string(),
            index: 7
        }
    );
    assert!(msg(k_nearest(&p, &bad, 1).unwrap_err()).starts_with("queries:"));
    let mut out = vec![0; 7];
    assert!(matches!(
        farthest_point_sample_batch(&p, 2, 5, &mut out),
        Err(GeometryError::Shape { .. })
    ));
    assert!(matches!(
        farthest_point_sample_batch(&p, 3, 5, &mut out),
        Err(GeometryError::Shape { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn random_clouds_agree_with_the_definitions(
        seed in 0u64..1_000_000, n in 1usize..60, r in 0.01f64..2.0, k in 1usize..10,
    ) {
        let p = cloud(seed, n);
        let m = 1 + (seed as usize) % n;
        let idx = farthest_point_sample(&p, m).unwrap();
        prop_assert_eq!(&idx, &fps_reference(&p, m));
        let c: Vec<Point> = idx.iter().map(|&i| p[i as usize]).collect();
        let g = ball_query(&p, &c, r, k).unwrap();
        for (cc, row) in c.iter().zip(g.chunks(k)) {
            prop_assert_eq!(row, &ball_reference(&p, cc, r, k)[..]);
        }
        let kk = k.min(m);
        let (nn, _) = k_nearest(&c, &p, kk).unwrap();
        for (q, row) in p.iter().zip(nn.chunks(kk)) {
            prop_assert_eq!(row, &knn_reference(&c, q, kk)[..]);
        }
    }
}
