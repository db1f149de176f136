//! K's phases timed apart, on the arrays `benches/bench_refs.py --phases` writes: the weld,
//! the edge table alone (every block built, sorted and split, nothing measured), and the
//! whole `shape_complexity`. The extension module's allocator is installed, as in Python.
//!
//!     cargo run --release --example k_phases -- VERTICES.f64 FACES.i64 [REPEAT]
//!
//! The files hold little-endian `f64` vertex triples and `i64` index triples.

use std::hint::black_box;
use std::time::Instant;

use meshbits::adjacency::map_edge_blocks;
use meshbits::complexity::{Estimator, Tolerances, shape_complexity};
use meshbits::weld::weld_identical;

/// The extension module's allocator (with the `python` feature the library installs it).
#[cfg(not(feature = "python"))]
#[global_allocator]
static ALLOCATOR: meshbits::alloc::HugePageAlloc = meshbits::alloc::HugePageAlloc;

fn triples<T>(path: &str, parse: fn([u8; 8]) -> T) -> Vec<[T; 3]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    assert_eq!(bytes.len() % 24, 0, "{path}: not a whole number of triples");
    bytes
        .chunks_exact(24)
        .map(|t| std::array::from_fn(|k| parse(t[8 * k..8 * k + 8].try_into().unwrap())))
        .collect()
}

/// Best of `repeat` calls, in milliseconds.
fn best(repeat: usize, mut run: impl FnMut()) -> f64 {
    (0..repeat)
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    assert!(
        args.len() >= 3,
        "usage: k_phases VERTICES.f64 FACES.i64 [REPEAT]"
    );
    let vertices = triples(&args[1], f64::from_le_bytes);
    let faces = triples(&args[2], i64::from_le_bytes);
    let repeat = args
        .get(3)
        .map_or(15, |r| r.parse().expect("REPEAT is a count"));
    let tol = Tolerances::default();
    let k = || {
        shape_complexity(&vertices, &faces, Estimator::Hybrid, true, false, &tol)
            .expect("a valid mesh")
    };
    let k_raw = k().k_raw;
    let weld = best(repeat, || {
        black_box(weld_identical(&vertices).merged);
    });
    let table = best(repeat, || {
        let (blocks, _) = map_edge_blocks(&faces, vertices.len(), |b| b.len()).expect("valid");
        black_box(blocks);
    });
    let whole = best(repeat, || {
        black_box(k().k_raw);
    });
    println!(
        "{} faces, {} threads, best of {repeat}; K_raw = {k_raw:.6}",
        faces.len(),
        rayon::current_num_threads()
    );
    println!("| phase | ms |\n|---|---:|");
    println!("| weld (hash partitions) | {weld:.1} |");
    println!("| edge table alone (chunks, blocks, sorted runs) | {table:.1} |");
    println!("| shape_complexity, whole | {whole:.1} |");
}
