//! Parse throughput of kinmo's OBJ loader against other maintained OBJ crates and a plain
//! read of the same bytes (issue 24, item 1: "measure against another maintained crate if
//! one is faster").
//!
//! ```text
//! cargo run --release -p kinmo-geometry --example obj_parsers -- [--repeat R] FILE...
//! ```
//!
//! Every file is read once into memory; then each repeat times, over all files, one thread:
//!
//! - `plain read`: `std::fs::read` of every file (page cache warm), the parse limit;
//! - `kinmo load_obj`: [`kinmo_geometry::mesh::load_obj`] (read, checks, `tobj`, f64);
//! - `tobj`: `tobj::load_obj_buf` on the in-memory bytes, as `load_obj` calls it;
//! - `obj`: `obj::ObjData::load_buf` (f32 positions);
//! - `mesh-loader`: `mesh_loader::obj::from_slice` (f32, one vertex per face corner).
//!
//! It prints one line per parser: the median MB/s over repeats, the ratio to the plain
//! read's median, the vertices it returned and the files it failed on. A parser that
//! returns a different vertex count does not give kinmo's vertex/face arrays.

use std::path::PathBuf;
use std::time::Instant;

/// A parser: a name and a function from a file's path and bytes to its vertex count.
type Parser = (&'static str, fn(&PathBuf, &[u8]) -> Option<usize>);

fn plain_read(path: &PathBuf, _: &[u8]) -> Option<usize> {
    std::fs::read(path).ok().map(|b| b.len())
}

fn kinmo_load(path: &PathBuf, _: &[u8]) -> Option<usize> {
    kinmo_geometry::mesh::load_obj(path)
        .ok()
        .map(|m| m.vertices().len())
}

fn tobj_buf(_: &PathBuf, bytes: &[u8]) -> Option<usize> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut &bytes[..], &opts, |_| {
        Ok((Vec::new(), Default::default()))
    })
    .ok()?;
    Some(models.iter().map(|m| m.mesh.positions.len() / 3).sum())
}

fn obj_crate(_: &PathBuf, bytes: &[u8]) -> Option<usize> {
    obj::ObjData::load_buf(bytes).ok().map(|o| o.position.len())
}

fn mesh_loader(_: &PathBuf, bytes: &[u8]) -> Option<usize> {
    let scene = mesh_loader::obj::from_slice(bytes, None, |_| Ok(Vec::<u8>::new())).ok()?;
    Some(scene.meshes.iter().map(|m| m.vertices.len()).sum())
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut repeat = 5usize;
    if let Some(i) = args.iter().position(|a| a == "--repeat") {
        repeat = args
            .get(i + 1)
            .and_then(|r| r.parse().ok())
            .expect("--repeat takes a positive integer");
        args.drain(i..i + 2);
    }
    let files: Vec<PathBuf> = args.into_iter().map(PathBuf::from).collect();
    if files.is_empty() {
        eprintln!("usage: obj_parsers [--repeat R] FILE...");
        std::process::exit(2);
    }
    let bytes: Vec<Vec<u8>> = files
        .iter()
        .map(|f| std::fs::read(f).unwrap_or_default())
        .collect();
    let mb = bytes.iter().map(Vec::len).sum::<usize>() as f64 / 1e6;
    let parsers: [Parser; 5] = [
        ("plain read", plain_read),
        ("kinmo load_obj (tobj, f64)", kinmo_load),
        ("tobj::load_obj_buf (f64)", tobj_buf),
        ("obj 0.10 (f32)", obj_crate),
        ("mesh-loader 0.1 (f32)", mesh_loader),
    ];
    let mut rates: Vec<Vec<f64>> = vec![Vec::new(); parsers.len()];
    let mut counts = vec![(0usize, 0usize); parsers.len()];
    for _ in 0..repeat {
        for (k, (_, parse)) in parsers.iter().enumerate() {
            let t = Instant::now();
            let (mut vertices, mut failed) = (0usize, 0usize);
            for (path, b) in files.iter().zip(&bytes) {
                match parse(path, b) {
                    Some(v) => vertices += v,
                    None => failed += 1,
                }
            }
            rates[k].push(mb / t.elapsed().as_secs_f64());
            counts[k] = (vertices, failed);
        }
    }
    println!(
        "{} files, {mb:.1} MB, median of {repeat} repeats, one thread",
        files.len()
    );
    println!("| parser | MB/s | of plain read | vertices returned | files failed |");
    println!("|---|---:|---:|---:|---:|");
    let read = median(rates[0].clone());
    for (k, (name, _)) in parsers.iter().enumerate() {
        let rate = median(rates[k].clone());
        let vertices = if k == 0 {
            "-".to_string()
        } else {
            counts[k].0.to_string()
        };
        println!(
            "| {name} | {rate:.0} | {:.1}% | {vertices} | {} |",
            100.0 * rate / read,
            counts[k].1
        );
    }
}
