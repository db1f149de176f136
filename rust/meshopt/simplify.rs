//! Error-bounded, attribute-aware edge-collapse simplification (see *Simplification* in
//! the [module docs](super)).

use glam::{DVec3, Vec3};

use crate::error::{MeshError, check_finite, check_indices};
use crate::quantize::bounding_box;
use crate::weld::weld_identical;

/// Most attributes meshoptimizer weighs per vertex.
pub const MAX_ATTRIBUTES: usize = 32;

/// Per-vertex attributes for the attribute-aware simplifier: `values` holds `weights.len()`
/// floats per vertex (normals, UVs, colours...), each attribute weighed against position
/// error by its weight (an attribute difference of 1 costs like `weight` mesh units of
/// distance).
#[derive(Debug, Clone, Copy)]
pub struct Attributes<'a> {
    pub values: &'a [f32],
    pub weights: &'a [f32],
}

/// What to simplify to, and what to keep.
#[derive(Debug, Clone, Copy, Default)]
pub struct Request<'a> {
    /// Stop at this many triangles or fewer (`None`: as far as `target_error` allows; with
    /// neither limit, an open surface may vanish).
    pub target_faces: Option<usize>,
    /// Stop before the error would pass this length (mesh units; `None`: no limit).
    pub target_error: Option<f64>,
    /// Keep the vertices of open borders in place.
    pub lock_border: bool,
    /// One flag per vertex: `true` keeps the vertex.
    pub locked: Option<&'a [bool]>,
    /// Attributes to weigh, per vertex.
    pub attributes: Option<Attributes<'a>>,
    /// Let small disconnected pieces vanish when their error fits the target.
    pub prune: bool,
    /// Move each kept vertex (and its attributes) to where the collapse quadrics are least
    /// (`meshopt_simplifyWithUpdate`), instead of keeping input vertices where they were.
    pub update_positions: bool,
    /// First merge vertices with bit-identical coordinates (each into the smallest such
    /// index), so that a triangle soup (an STL file) has shared edges and no seams. Not
    /// for meshes whose duplicated vertices carry attribute seams.
    pub weld: bool,
}

/// The simplified mesh over a subset of the input vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Simplified {
    /// Input index of each kept vertex, increasing.
    pub vertex_ids: Vec<u32>,
    /// Faces over the kept vertices (indices into `vertex_ids`), in the simplifier's order.
    pub faces: Vec<[u32; 3]>,
    /// The simplifier's error estimate (length, mesh units).
    pub error: f64,
    /// With `update_positions`: the kept vertices' new positions (length), which the
    /// simplifier moved to where its quadrics are least.
    pub positions: Option<Vec<[f64; 3]>>,
    /// With `update_positions` and attributes: their new values, per kept vertex.
    pub attributes: Option<Vec<f32>>,
}

/// Simplifies `faces` over `vertices` as `request` asks. Coordinates are handed to the
/// simplifier in f32 relative to the bounding-box centre.
pub fn simplify(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    request: &Request<'_>,
) -> Result<Simplified, MeshError> {
    let target_error = check_request(vertices, faces, request)?;
    let welded: Vec<[u32; 3]>;
    let faces = if request.weld {
        welded = welded_faces(vertices, faces)?;
        &welded[..]
    } else {
        faces
    };
    // The simplifier sees only the referenced vertices: an unreferenced copy of a position
    // would read as an attribute seam there.
    let used = compact(faces.as_flattened(), vertices.len(), 0.0);
    let ids = &used.vertex_ids;
    let (lo, hi) = bounding_box(vertices).unwrap_or(([0.0; 3], [0.0; 3]));
    let centre = (DVec3::from_array(lo) + DVec3::from_array(hi)) * 0.5;
    let mut input = SimplifierInput::gather(vertices, ids, centre, request);
    let mut options = meshopt::SimplifyOptions::ErrorAbsolute;
    if request.lock_border {
        options |= meshopt::SimplifyOptions::LockBorder;
    }
    if request.prune {
        options |= meshopt::SimplifyOptions::Prune;
    }
    let target_index_count = 3 * request.target_faces.unwrap_or(0).min(faces.len());
    let (result, error) = input.run(
        used.faces.as_flattened(),
        target_index_count,
        target_error,
        options,
        request.update_positions,
    );
    let mut out = compact(&result, input.positions.len(), f64::from(error));
    if request.update_positions {
        input.updated(&mut out, centre);
    }
    for id in &mut out.vertex_ids {
        *id = ids[*id as usize];
    }
    Ok(out)
}

/// Refuses what the simplifier cannot take (no faces, non-finite coordinates, indices out
/// of range, a lock flag or attribute row per vertex missing, too many attributes,
/// negative or non-finite weights and values); returns the target error as the simplifier
/// takes it (f32, `f32::MAX` for none).
fn check_request(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    request: &Request<'_>,
) -> Result<f32, MeshError> {
    if faces.is_empty() {
        return Err(MeshError::Empty("the mesh has no faces to simplify".into()));
    }
    check_finite(vertices)?;
    check_indices(faces, vertices.len())?;
    let n = vertices.len();
    if let Some(locked) = request.locked
        && locked.len() != n
    {
        return Err(MeshError::Parameter(format!(
            "locked has {} flags for {n} vertices",
            locked.len()
        )));
    }
    if let Some(a) = request.attributes {
        check_attributes(a, n)?;
    }
    match request.target_error {
        None => Ok(f32::MAX),
        Some(e) if e.is_finite() && e >= 0.0 => Ok((e as f32).min(f32::MAX)),
        Some(e) => Err(MeshError::Parameter(format!(
            "target error must be finite and >= 0, got {e}"
        ))),
    }
}

/// Refuses attributes that are not `weights.len() <= MAX_ATTRIBUTES` finite values per
/// vertex of `n`, or whose weights are negative or not finite.
fn check_attributes(a: Attributes<'_>, n: usize) -> Result<(), MeshError> {
    let k = a.weights.len();
    if k > MAX_ATTRIBUTES {
        return Err(MeshError::Parameter(format!(
            "at most {MAX_ATTRIBUTES} attributes per vertex, got {k}"
        )));
    }
    if a.values.len() != n * k {
        return Err(MeshError::Parameter(format!(
            "attributes hold {} values for {n} vertices of {k} attributes",
            a.values.len()
        )));
    }
    if let Some(w) = a.weights.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(MeshError::Parameter(format!(
            "attribute weight {w} is {}: weights must be finite and >= 0",
            a.weights[w]
        )));
    }
    if let Some(i) = a.values.iter().position(|v| !v.is_finite()) {
        return Err(MeshError::Parameter(format!(
            "the attributes of vertex {} are not finite",
            i / k.max(1)
        )));
    }
    Ok(())
}

/// `faces` with identical vertices merged ([`weld_identical`]) and the faces that then
/// repeat a vertex dropped; refuses a mesh left with none.
fn welded_faces(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Result<Vec<[u32; 3]>, MeshError> {
    let weld = weld_identical(vertices);
    let welded: Vec<[u32; 3]> = faces
        .iter()
        .map(|t| weld.face(t))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
        .collect();
    if welded.is_empty() {
        return Err(MeshError::Empty(
            "every face repeats a vertex once identical vertices are merged".into(),
        ));
    }
    Ok(welded)
}

/// What the simplifier reads (and, with `update_positions`, rewrites) per referenced
/// vertex: f32 positions relative to the centre, lock flags, and attribute values with
/// their weights.
struct SimplifierInput<'a> {
    positions: Vec<[f32; 3]>,
    locks: Vec<u8>,
    values: Vec<f32>,
    weights: &'a [f32],
}

impl<'a> SimplifierInput<'a> {
    /// The inputs of the vertices `ids` (the referenced ones, in order).
    fn gather(
        vertices: &[[f64; 3]],
        ids: &[u32],
        centre: DVec3,
        request: &Request<'a>,
    ) -> SimplifierInput<'a> {
        let positions: Vec<[f32; 3]> = ids
            .iter()
            .map(|&i| {
                (DVec3::from_array(vertices[i as usize]) - centre)
                    .as_vec3()
                    .to_array()
            })
            .collect();
        let locks: Vec<u8> = match request.locked {
            Some(locked) => ids.iter().map(|&i| u8::from(locked[i as usize])).collect(),
            None => vec![0; ids.len()],
        };
        let (values, weights): (Vec<f32>, &[f32]) = match request.attributes {
            Some(a) if !a.weights.is_empty() => {
                let k = a.weights.len();
                let gathered = ids
                    .iter()
                    .flat_map(|&i| &a.values[i as usize * k..(i as usize + 1) * k])
                    .copied()
                    .collect();
                (gathered, a.weights)
            }
            _ => (Vec::new(), &[]),
        };
        SimplifierInput {
            positions,
            locks,
            values,
            weights,
        }
    }

    /// Runs `meshopt_simplifyWithAttributes` on `indices` (over the gathered vertices), or
    /// with `update` `meshopt_simplifyWithUpdate`, which also moves the positions and
    /// values in place; returns the kept indices and the error reached (length).
    fn run(
        &mut self,
        indices: &[u32],
        target_index_count: usize,
        target_error: f32,
        options: meshopt::SimplifyOptions,
        update: bool,
    ) -> (Vec<u32>, f32) {
        let stride = 4 * self.weights.len();
        let mut result = vec![0u32; indices.len()];
        let mut error = 0.0f32;
        // SAFETY: every precondition of meshopt_simplifyWithAttributes holds: indices are
        // below `positions.len()` (compacted) and a multiple of 3; the position stride is
        // 12 bytes; the target is at most the index count and the error is finite and
        // >= 0; `values` holds `weights.len()` floats per vertex at 4 bytes per float (at
        // most 32 floats, 128 bytes); weights are >= 0; `locks` has one byte per vertex;
        // `result` has room for every input index.
        let values_ptr = if stride > 0 {
            self.values.as_mut_ptr()
        } else {
            std::ptr::null_mut()
        };
        let weights_ptr = if stride > 0 {
            self.weights.as_ptr()
        } else {
            std::ptr::null()
        };
        let kept = if update {
            result.copy_from_slice(indices);
            // SAFETY: as for meshopt_simplifyWithAttributes below; the positions and
            // values it updates in place are this input's own copies.
            unsafe {
                meshopt::ffi::meshopt_simplifyWithUpdate(
                    result.as_mut_ptr(),
                    result.len(),
                    self.positions.as_mut_ptr().cast(),
                    self.positions.len(),
                    12,
                    values_ptr,
                    stride,
                    weights_ptr,
                    self.weights.len(),
                    self.locks.as_ptr(),
                    target_index_count,
                    target_error,
                    options.bits(),
                    &mut error,
                )
            }
        } else {
            // SAFETY: see above.
            unsafe {
                meshopt::ffi::meshopt_simplifyWithAttributes(
                    result.as_mut_ptr(),
                    indices.as_ptr(),
                    indices.len(),
                    self.positions.as_ptr().cast(),
                    self.positions.len(),
                    12,
                    values_ptr,
                    stride,
                    weights_ptr,
                    self.weights.len(),
                    self.locks.as_ptr(),
                    target_index_count,
                    target_error,
                    options.bits(),
                    &mut error,
                )
            }
        };
        result.truncate(kept);
        (result, error)
    }

    /// The moved positions (back in the caller's frame, `+ centre`) and attribute values
    /// of the vertices `out` kept, after [`run`](Self::run) with `update`.
    fn updated(&self, out: &mut Simplified, centre: DVec3) {
        let k = self.weights.len();
        out.positions = Some(
            out.vertex_ids
                .iter()
                .map(|&i| {
                    (DVec3::from(Vec3::from_array(self.positions[i as usize])) + centre).to_array()
                })
                .collect(),
        );
        if k > 0 {
            out.attributes = Some(
                out.vertex_ids
                    .iter()
                    .flat_map(|&i| &self.values[i as usize * k..(i as usize + 1) * k])
                    .copied()
                    .collect(),
            );
        }
    }
}

/// The kept vertices of an index list over `n` vertices, and its faces over them.
fn compact(indices: &[u32], n: usize, error: f64) -> Simplified {
    let mut new_id = vec![u32::MAX; n];
    for &i in indices {
        new_id[i as usize] = 0;
    }
    let mut vertex_ids = Vec::new();
    for (i, id) in new_id.iter_mut().enumerate() {
        if *id == 0 {
            *id = vertex_ids.len() as u32;
            vertex_ids.push(i as u32);
        }
    }
    let faces = indices
        .chunks_exact(3)
        .map(|t| {
            [
                new_id[t[0] as usize],
                new_id[t[1] as usize],
                new_id[t[2] as usize],
            ]
        })
        .collect();
    Simplified {
        vertex_ids,
        faces,
        error,
        positions: None,
        attributes: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `(n + 1) x (n + 1)` grid on the unit square, bent into `z = bend * x^2`.
    fn sheet(n: u32, bend: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        crate::test_meshes::grid(n, |x, _| bend * x * x)
    }

    #[test]
    fn a_flat_sheet_collapses_to_two_triangles_at_a_small_error() {
        let (v, f) = sheet(20, 0.0);
        let request = Request {
            target_error: Some(1e-3),
            ..Request::default()
        };
        let s = simplify(&v, &f, &request).unwrap();
        assert_eq!(s.faces.len(), 2);
        assert!(s.error <= 1e-3);
        // The corners of the open border survive.
        for corner in [0u32, 20, 420, 440] {
            assert!(s.vertex_ids.contains(&corner));
        }
    }

    #[test]
    fn the_error_target_bounds_the_reported_error_and_keeps_vertices_in_place() {
        let (v, f) = sheet(30, 0.5);
        for target in [1e-4, 1e-3, 1e-2] {
            let s = simplify(
                &v,
                &f,
                &Request {
                    target_error: Some(target),
                    ..Request::default()
                },
            )
            .unwrap();
            assert!(s.error <= target * (1.0 + 1e-5), "{} > {target}", s.error);
            assert!(s.faces.len() < f.len());
            assert!(s.vertex_ids.windows(2).all(|w| w[0] < w[1]));
            let max_id = s.vertex_ids.len() as u32;
            assert!(s.faces.iter().flatten().all(|&i| i < max_id));
        }
    }

    #[test]
    fn locked_vertices_and_borders_stay() {
        let (v, f) = sheet(12, 0.3);
        let mut locked = vec![false; v.len()];
        locked[6 * 13 + 6] = true;
        let s = simplify(
            &v,
            &f,
            &Request {
                target_faces: Some(1),
                lock_border: true,
                locked: Some(&locked),
                ..Request::default()
            },
        )
        .unwrap();
        assert!(s.vertex_ids.contains(&(6 * 13 + 6)));
        let border = (0..13u32).flat_map(|i| [i, 12 * 13 + i, 13 * i, 13 * i + 12]);
        for b in border {
            assert!(s.vertex_ids.contains(&b), "border vertex {b} was removed");
        }
    }

    #[test]
    fn a_face_target_is_reached_on_a_closed_surface() {
        // An octahedron subdivided by a sheet on each face would be long; a bent sheet
        // without border locks reaches small counts as well.
        let (v, f) = sheet(16, 0.4);
        let s = simplify(
            &v,
            &f,
            &Request {
                target_faces: Some(100),
                ..Request::default()
            },
        )
        .unwrap();
        assert!(
            s.faces.len() <= 100 && s.faces.len() >= 50,
            "{}",
            s.faces.len()
        );
    }

    #[test]
    fn welding_turns_a_triangle_soup_into_a_surface() {
        let (v, f) = sheet(10, 0.2);
        let soup_v: Vec<[f64; 3]> = f.iter().flatten().map(|&i| v[i as usize]).collect();
        let soup_f: Vec<[u32; 3]> = (0..f.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let request = Request {
            target_error: Some(1e-2),
            ..Request::default()
        };
        let unwelded = simplify(&soup_v, &soup_f, &request).unwrap();
        let welded = simplify(
            &soup_v,
            &soup_f,
            &Request {
                weld: true,
                ..request
            },
        )
        .unwrap();
        assert_eq!(
            unwelded.faces.len(),
            soup_f.len(),
            "a soup has only borders"
        );
        assert!(
            welded.faces.len() < soup_f.len() / 4,
            "{}",
            welded.faces.len()
        );
    }

    #[test]
    fn bad_requests_are_refused() {
        let (v, f) = sheet(4, 0.0);
        let bad = [
            Request {
                target_error: Some(f64::NAN),
                ..Request::default()
            },
            Request {
                target_error: Some(-1.0),
                ..Request::default()
            },
            Request {
                locked: Some(&[true]),
                ..Request::default()
            },
            Request {
                attributes: Some(Attributes {
                    values: &[0.0; 3],
                    weights: &[1.0],
                }),
                ..Request::default()
            },
            Request {
                attributes: Some(Attributes {
                    values: &[0.0; 25],
                    weights: &[-1.0],
                }),
                ..Request::default()
            },
        ];
        for request in bad {
            assert!(simplify(&v, &f, &request).is_err());
        }
        assert!(simplify(&v, &[[0, 1, 99]], &Request::default()).is_err());
        assert!(simplify(&v, &[], &Request::default()).is_err());
    }

    #[test]
    fn attributes_keep_a_seam() {
        // Two flat halves whose shared column carries different UVs on each side: the seam
        // vertices are duplicated (same position, different index) and must survive as a line.
        let (mut v, mut f) = sheet(10, 0.0);
        let n = v.len() as u32;
        let seam: Vec<u32> = (0..11u32).map(|j| j * 11 + 5).collect();
        for &s in &seam {
            v.push(v[s as usize]);
        }
        for t in f.iter_mut() {
            let right = t.iter().all(|&i| i % 11 >= 5);
            if right {
                for i in t.iter_mut() {
                    if let Some(k) = seam.iter().position(|&s| s == *i) {
                        *i = n + k as u32;
                    }
                }
            }
        }
        let uv: Vec<f32> = (0..v.len())
            .flat_map(|i| {
                let p = v[i];
                let side = if i as u32 >= n { 1.0 } else { 0.0 };
                [p[0] as f32 + side, p[1] as f32]
            })
            .collect();
        let s = simplify(
            &v,
            &f,
            &Request {
                target_error: Some(1e-2),
                attributes: Some(Attributes {
                    values: &uv,
                    weights: &[1.0, 1.0],
                }),
                ..Request::default()
            },
        )
        .unwrap();
        assert!(s.faces.len() < f.len() / 4, "{} faces left", s.faces.len());
        let kept_seam = s
            .vertex_ids
            .iter()
            .filter(|&&i| (i as usize) < v.len() && (v[i as usize][0] - 0.5).abs() < 1e-12)
            .count();
        // Both ends on the border, on both sides of the seam.
        assert!(
            kept_seam >= 4,
            "the seam lost its vertices ({kept_seam} left)"
        );
    }
}
