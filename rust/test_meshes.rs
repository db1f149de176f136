//! Meshes the unit tests share.

/// The unit square `[0, 1]²` split into `2 n²` triangles, each vertex lifted to
/// `z = height(x, y)` (length).
pub fn grid(n: u32, height: impl Fn(f64, f64) -> f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
            v.push([x, y, height(x, y)]);
        }
    }
    let mut f = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let k = j * (n + 1) + i;
            f.push([k, k + 1, k + n + 2]);
            f.push([k, k + n + 2, k + n + 1]);
        }
    }
    (v, f)
}
