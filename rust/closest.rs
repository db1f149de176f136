//! The closest point of one triangle to a query point, in f64.
//!
//! Region-based method of Ericson, *Real-Time Collision Detection* (2005), Sec. 5.1.5:
//! with `ap = p - a`, the six dot products `d1 = ab·ap`, `d2 = ac·ap`,
//! `d3 = ab·bp = d1 - ab·ab`, `d4 = ac·bp = d2 - ab·ac`, `d5 = ab·cp = d1 - ab·ac`,
//! `d6 = ac·cp = d2 - ac·ac` decide which of the seven Voronoi regions of the triangle
//! (three vertices, three edges, the face) holds `p`; the scaled barycentric coordinates
//! `va = d3 d6 - d5 d4`, `vb = d5 d2 - d1 d6`, `vc = d1 d4 - d3 d2` separate edge regions
//! from the face. [`PreparedTriangle`] keeps `ab·ab`, `ab·ac` and `ac·ac`, so a query costs
//! two dot products plus the region tests.
//!
//! In the face region the closest point is the orthogonal projection
//! `q = p - n (ap·n) / |n|²` with `n = ab × ac`, rather than Ericson's
//! `a + (vb ab + vc ac) / (va + vb + vc)`, whose denominator `va + vb + vc = |n|²` comes
//! from differences of products of dot products. The distance is `|p - q|` for the returned
//! point.
//!
//! Precision. Let `L` be the longest edge and `s = |ab × ac| / L²` (twice the area over
//! `L²`; about the width of the triangle over `L`). The region tests and `n` carry relative
//! errors of about `ε / s` (`ε = 2⁻⁵²`), so a point within about `ε L / s` (times
//! `(|ap| / L)²` far away) of an edge may be put on the wrong side of it, where the face and
//! edge answers differ by at most that much. For well-shaped triangles this is rounding;
//! it grows on slivers. Triangles with `s² ≤ DEGENERATE_RATIO2 = 1e-16` (zero area,
//! collinear corners, repeated vertices, and slivers narrower than `1e-8 L`) are handled as
//! the union of their three edges, each a segment (a point when its ends coincide): exact
//! for degenerate triangles, and within the sliver's width (`≤ 1e-8 L`) otherwise. So the
//! worst case, a sliver at the threshold, is about `1e-8 L`; a triangle with `s ≥ 1e-3`
//! is within about `1e-13 L`. Lengths are in the mesh's unit; squared distances in that
//! unit squared.

use std::cmp::Ordering;

use glam::DVec3;

/// `(2 area / L²)²`, `L` the longest edge, at or below which a triangle counts as
/// degenerate and is handled as its edges (dimensionless); see the module docs.
pub const DEGENERATE_RATIO2: f64 = 1e-16;

/// A triangle with the quantities a closest-point query reuses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreparedTriangle {
    /// First corner (length).
    pub a: DVec3,
    /// `b - a` (length).
    pub ab: DVec3,
    /// `c - a` (length).
    pub ac: DVec3,
    /// `ab·ab` (length²).
    aa: f64,
    /// `ab·ac` (length²).
    abac: f64,
    /// `ac·ac` (length²).
    cc: f64,
    /// Zero area or a sliver: handled as three segments.
    degenerate: bool,
}

/// Closest point of a segment `a + t ab`, `t ∈ [0, 1]`, to the point `a + ap`; returns
/// `t`. A zero-length segment returns `t = 0`.
#[inline]
#[must_use]
fn segment_parameter(ap: DVec3, ab: DVec3, aa: f64) -> f64 {
    if aa > 0.0 {
        (ap.dot(ab) / aa).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

impl PreparedTriangle {
    /// Prepares the triangle `(a, b, c)`.
    #[inline]
    #[must_use]
    pub fn new(a: DVec3, b: DVec3, c: DVec3) -> Self {
        let (ab, ac) = (b - a, c - a);
        let (aa, abac, cc) = (ab.length_squared(), ab.dot(ac), ac.length_squared());
        let nn = ab.cross(ac).length_squared();
        let longest2 = aa.max(cc).max((ac - ab).length_squared());
        // Not "greater" also when a product overflowed to NaN.
        let limit = DEGENERATE_RATIO2 * longest2 * longest2;
        let degenerate = nn.partial_cmp(&limit) != Some(Ordering::Greater);
        PreparedTriangle {
            a,
            ab,
            ac,
            aa,
            abac,
            cc,
            degenerate,
        }
    }

    /// Whether the triangle is handled as its three edges (see the module docs).
    #[inline]
    #[must_use]
    pub fn is_degenerate(&self) -> bool {
        self.degenerate
    }

    /// The corners `(a, b, c)`.
    #[inline]
    #[must_use]
    pub fn corners(&self) -> [DVec3; 3] {
        [self.a, self.a + self.ab, self.a + self.ac]
    }

    /// The closest point of the triangle to `p` and the squared distance to it.
    #[inline]
    #[must_use]
    pub fn closest(&self, p: DVec3) -> (DVec3, f64) {
        let ap = p - self.a;
        if self.degenerate {
            return self.closest_on_edges(p, ap);
        }
        let d1 = self.ab.dot(ap);
        let d2 = self.ac.dot(ap);
        let q = if d1 <= 0.0 && d2 <= 0.0 {
            self.a
        } else {
            let d3 = d1 - self.aa;
            let d4 = d2 - self.abac;
            if d3 >= 0.0 && d4 <= d3 {
                self.a + self.ab
            } else {
                let vc = d1 * d4 - d3 * d2;
                if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                    self.a + self.ab * (d1 / (d1 - d3))
                } else {
                    let d5 = d1 - self.abac;
                    let d6 = d2 - self.cc;
                    if d6 >= 0.0 && d5 <= d6 {
                        self.a + self.ac
                    } else {
                        let vb = d5 * d2 - d1 * d6;
                        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                            self.a + self.ac * (d2 / (d2 - d6))
                        } else {
                            let va = d3 * d6 - d5 * d4;
                            let (e43, e56) = (d4 - d3, d5 - d6);
                            if va <= 0.0 && e43 >= 0.0 && e56 >= 0.0 {
                                let w = e43 / (e43 + e56);
                                let b = self.a + self.ab;
                                b + (self.ac - self.ab) * w
                            } else {
                                // Face region: the orthogonal projection on the plane.
                                let n = self.ab.cross(self.ac);
                                p - n * (ap.dot(n) / n.length_squared())
                            }
                        }
                    }
                }
            }
        };
        (q, (p - q).length_squared())
    }

    /// The closest point of the three edges (segments) to `p`; `ap = p - a`.
    #[inline(never)]
    #[must_use]
    fn closest_on_edges(&self, p: DVec3, ap: DVec3) -> (DVec3, f64) {
        let bc = self.ac - self.ab;
        let candidates = [
            self.a + self.ab * segment_parameter(ap, self.ab, self.aa),
            self.a + self.ac * segment_parameter(ap, self.ac, self.cc),
            self.a + self.ab + bc * segment_parameter(ap - self.ab, bc, bc.length_squared()),
        ];
        let mut best = (candidates[0], (p - candidates[0]).length_squared());
        for &q in &candidates[1..] {
            let d2 = (p - q).length_squared();
            if d2 < best.1 {
                best = (q, d2);
            }
        }
        best
    }
}

/// The closest point of the triangle `(a, b, c)` to `p`, and the squared distance to it
/// (length²). For many queries against one triangle, keep a [`PreparedTriangle`].
#[inline]
#[must_use]
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, f64) {
    PreparedTriangle::new(a, b, c).closest(p)
}

/// Covering radius of a triangle by its corners: `max over q in the triangle of
/// min(|q - a|, |q - b|, |q - c|)` (length).
///
/// Every point of the triangle lies within this distance of a corner. The maximum of
/// the distance to the nearest corner is reached at the circumcentre when it lies in the
/// triangle (acute or right triangles: the circumradius), and otherwise where the
/// perpendicular bisector of two corners crosses an edge; all those candidates are
/// evaluated. Collinear corners and repeated vertices need no special case: the
/// circumcentre is then skipped and the bisectors cross the segment at the midpoints.
/// Midpoint subdivision makes four triangles similar to the parent with half its size, so
/// their radius is half the parent's.
#[must_use]
pub fn covering_radius(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let corners = [a, b, c];
    let nearest_corner = |q: DVec3| {
        corners
            .iter()
            .map(|&v| (q - v).length())
            .fold(f64::INFINITY, f64::min)
    };
    let mut radius = 0.0_f64;
    // Circumcentre, when it lies inside (all corner angles at most 90 degrees).
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(ac);
    let nn = n.length_squared();
    let acute = ab.dot(ac) >= 0.0 && (a - b).dot(c - b) >= 0.0 && (a - c).dot(b - c) >= 0.0;
    if acute && nn > DEGENERATE_RATIO2 * ab.length_squared() * ac.length_squared() {
        let centre = a
            + (n.cross(ab) * ac.length_squared() + ac.cross(n) * ab.length_squared()) / (2.0 * nn);
        if centre.is_finite() {
            radius = radius.max(nearest_corner(centre));
        }
    }
    // Bisector of each corner pair against each edge.
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        let w = corners[j] - corners[i];
        if w == DVec3::ZERO {
            continue;
        }
        let mid = (corners[i] + corners[j]) * 0.5;
        for (k, l) in [(0, 1), (1, 2), (2, 0)] {
            let edge = corners[l] - corners[k];
            let denom = edge.dot(w);
            if denom == 0.0 {
                continue;
            }
            let t = (mid - corners[k]).dot(w) / denom;
            if (0.0..=1.0).contains(&t) {
                radius = radius.max(nearest_corner(corners[k] + edge * t));
            }
        }
    }
    radius
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the closest of a dense barycentric grid and of the edges sampled
    /// finely; an upper bound on the true distance within the grid spacing.
    fn brute(p: DVec3, a: DVec3, b: DVec3, c: DVec3, steps: usize) -> f64 {
        let mut best = f64::INFINITY;
        for i in 0..=steps {
            for j in 0..=(steps - i) {
                let (v, w) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let q = a + (b - a) * v + (c - a) * w;
                best = best.min((p - q).length());
            }
        }
        best
    }

    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn random_point(state: &mut u64) -> DVec3 {
        DVec3::new(lcg(state), lcg(state), lcg(state))
    }

    #[test]
    fn every_region_of_a_right_triangle() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let cases = [
            (DVec3::new(-1.0, -1.0, 0.0), a),
            (DVec3::new(2.0, -0.5, 0.0), b),
            (DVec3::new(-0.5, 2.0, 1.0), c),
            (DVec3::new(0.5, -1.0, 0.0), DVec3::new(0.5, 0.0, 0.0)),
            (DVec3::new(-1.0, 0.25, 3.0), DVec3::new(0.0, 0.25, 0.0)),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.5, 0.5, 0.0)),
            (DVec3::new(0.25, 0.25, -2.0), DVec3::new(0.25, 0.25, 0.0)),
        ];
        for (p, expected) in cases {
            let (q, d2) = closest_point_on_triangle(p, a, b, c);
            assert!(
                (q - expected).length() < 1e-15,
                "{p} -> {q}, expected {expected}"
            );
            assert!((d2 - (p - expected).length_squared()).abs() < 1e-14);
        }
    }

    #[test]
    fn agrees_with_a_dense_grid_on_random_triangles() {
        let mut s = 7;
        for _ in 0..200 {
            let (a, b, c, p) = (
                random_point(&mut s),
                random_point(&mut s),
                random_point(&mut s),
                random_point(&mut s),
            );
            let (q, d2) = closest_point_on_triangle(p, a, b, c);
            let d = d2.sqrt();
            let grid = brute(p, a, b, c, 200);
            // The grid is coarser than the exact answer by at most its spacing.
            assert!(d <= grid + 1e-12, "{d} > {grid}");
            assert!(grid - d < 0.02, "{d} vs {grid}");
            assert!(((p - q).length() - d).abs() < 1e-14);
        }
    }

    #[test]
    fn degenerate_triangles_are_their_edges() {
        let p = DVec3::new(0.3, 1.0, 0.0);
        // Collinear corners, in every order.
        let (a, b, c) = (
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
        );
        for (x, y, z) in [(a, b, c), (b, c, a), (c, a, b), (a, c, b)] {
            let (q, d2) = closest_point_on_triangle(p, x, y, z);
            assert!((q - DVec3::new(0.3, 0.0, 0.0)).length() < 1e-15);
            assert!((d2 - 1.0).abs() < 1e-15);
        }
        // Repeated vertices: a segment, then a point.
        let (_, d2) = closest_point_on_triangle(p, a, a, b);
        assert!((d2 - 1.0).abs() < 1e-15);
        let (q, d2) = closest_point_on_triangle(p, b, b, b);
        assert_eq!(q, b);
        assert!((d2 - (p - b).length_squared()).abs() < 1e-15);
        assert!(PreparedTriangle::new(a, b, c).is_degenerate());
        assert!(!PreparedTriangle::new(a, b, DVec3::Y).is_degenerate());
    }

    #[test]
    fn slivers_keep_their_precision() {
        // Width 1e-6 of the length: not degenerate, ill-conditioned.
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::new(0.5, 1e-6, 0.0));
        assert!(!PreparedTriangle::new(a, b, c).is_degenerate());
        for (p, expected) in [
            (DVec3::new(0.5, 2e-7, 0.3), 0.3),
            (DVec3::new(0.25, 4e-7, -0.7), 0.7),
            (DVec3::new(0.25, -0.5, 0.0), 0.5),
            (DVec3::new(0.5, 0.5, 0.0), 0.5 - 1e-6),
            (DVec3::new(1.5, 0.0, 0.0), 0.5),
        ] {
            let (q, d2) = closest_point_on_triangle(p, a, b, c);
            assert!(
                (d2.sqrt() - expected).abs() < 1e-12,
                "{p}: {} vs {expected}",
                d2.sqrt()
            );
            assert!(((p - q).length_squared() - d2).abs() < 1e-15);
        }
    }

    #[test]
    fn points_on_the_triangle_are_at_distance_zero() {
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        );
        for p in [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (a + c) * 0.5] {
            let (_, d2) = closest_point_on_triangle(p, a, b, c);
            assert!(d2 < 1e-30, "{p}: {d2}");
        }
        let (_, d2) = closest_point_on_triangle((a + b + c) / 3.0, a, b, c);
        assert!(d2 < 1e-30);
    }

    #[test]
    fn covering_radius_of_known_triangles() {
        // Equilateral with unit circumradius.
        let s3 = 3.0_f64.sqrt();
        let (a, b, c) = (
            DVec3::X,
            DVec3::new(-0.5, s3 / 2.0, 0.0),
            DVec3::new(-0.5, -s3 / 2.0, 0.0),
        );
        assert!((covering_radius(a, b, c) - 1.0).abs() < 1e-12);
        // Right isosceles: the circumcentre is the hypotenuse's midpoint.
        let r = covering_radius(DVec3::ZERO, DVec3::X, DVec3::Y);
        assert!((r - 0.5_f64.sqrt()).abs() < 1e-12);
        // Collinear 0, 1, 4: the farthest point is the midpoint of [1, 4].
        let r = covering_radius(DVec3::ZERO, DVec3::X, DVec3::X * 4.0);
        assert!((r - 1.5).abs() < 1e-12);
        assert_eq!(covering_radius(DVec3::X, DVec3::X, DVec3::X), 0.0);
        assert!((covering_radius(DVec3::ZERO, DVec3::ZERO, DVec3::X * 2.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn covering_radius_bounds_a_dense_grid() {
        let mut s = 11;
        for _ in 0..100 {
            let (a, b, c) = (
                random_point(&mut s),
                random_point(&mut s),
                random_point(&mut s),
            );
            let r = covering_radius(a, b, c);
            let mut worst = 0.0_f64;
            let steps = 60;
            for i in 0..=steps {
                for j in 0..=(steps - i) {
                    let q = a
                        + (b - a) * (i as f64 / steps as f64)
                        + (c - a) * (j as f64 / steps as f64);
                    worst = worst.max((q - a).length().min((q - b).length()).min((q - c).length()));
                }
            }
            assert!(worst <= r * (1.0 + 1e-12), "{worst} > {r}");
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            assert!(worst >= r - longest / steps as f64, "{worst} << {r}");
        }
    }
}
