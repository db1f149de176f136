//! Batches of queries in the caller's frame: checked, recentred, searched in
//! [`coherent_order`] in parallel units, each search hinted by the previous answer.

use glam::DVec3;
use rayon::prelude::*;

use super::order::coherent_order;
use super::search::Nearest;
use super::tree::TriangleTree;
use crate::error::{MAX_EXTENT, MeshError, check_finite};

/// Queries per parallel work unit in [`TriangleTree::query`]; the hint carries over
/// inside a unit.
const QUERY_CHUNK: usize = 512;

/// Per query point: distance (length), closest point (caller's frame), face index.
pub type QueryResult = (Vec<f64>, Vec<[f64; 3]>, Vec<u32>);

impl TriangleTree {
    /// The first of `local` (points in the tree's frame) farther than [`MAX_EXTENT`] from
    /// its centre on some axis, with that distance: such points' squared distances approach
    /// the float64 range, and the f32 boxes cannot hold them.
    #[must_use]
    pub fn beyond_reach(&self, local: &[DVec3]) -> Option<(usize, f64)> {
        local
            .par_iter()
            .position_first(|p| p.abs().max_element() > MAX_EXTENT)
            .map(|i| (i, local[i].abs().max_element()))
    }

    /// Exact nearest triangle to each point (caller's frame), in parallel.
    ///
    /// Returns, per point, the distance (length), the closest point (caller's frame,
    /// length) and the face index. The points are searched in [`coherent_order`], each
    /// search starting from the previous answer. Results do not depend on the order or the
    /// thread count.
    pub fn query(&self, points: &[[f64; 3]]) -> Result<QueryResult, MeshError> {
        let local = self.local_points(points)?;
        let (order, hits) = self.search_coherent(&local, QUERY_CHUNK, 0.0, |hit| hit);
        let n = points.len();
        let (mut dist, mut closest, mut face) = (vec![0.0; n], vec![[0.0; 3]; n], vec![0u32; n]);
        for (&i, hit) in order.iter().zip(&hits) {
            let i = i as usize;
            dist[i] = hit.d2.sqrt();
            closest[i] = (hit.point + self.centre).to_array();
            face[i] = hit.face;
        }
        Ok((dist, closest, face))
    }

    /// Searches `local` points (recentred frame) in [`coherent_order`], in parallel units
    /// of `chunk` points, each search hinted by the previous answer of its unit and
    /// stopping below `stop_below_d2` (0: exact). Returns the order and, in that order,
    /// what `keep` takes of each answer.
    pub fn search_coherent<T: Send>(
        &self,
        local: &[DVec3],
        chunk: usize,
        stop_below_d2: f64,
        keep: impl Fn(Nearest) -> T + Sync,
    ) -> (Vec<u32>, Vec<T>) {
        let order = coherent_order(local);
        let kept = order
            .par_chunks(chunk)
            .flat_map_iter(|unit| {
                let mut stack = self.stack();
                let mut hint = u32::MAX;
                unit.iter()
                    .map(|&i| {
                        let hit = self
                            .nearest_local(local[i as usize], hint, stop_below_d2, &mut stack)
                            .expect("the tree is not empty");
                        hint = hit.slot;
                        keep(hit)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        (order, kept)
    }

    /// Which of `points` (caller's frame) lie farther than `distance` (length) from every
    /// triangle, decided exactly (`d(p) > distance`). A search stops at the first triangle
    /// within `distance` (usually the previous point's, or one in its subtree), so this
    /// costs far less than [`query`](Self::query) when most points are near the mesh.
    pub fn farther_than(&self, points: &[[f64; 3]], distance: f64) -> Result<Vec<bool>, MeshError> {
        if !(distance >= 0.0 && distance.is_finite()) {
            return Err(MeshError::Parameter(format!(
                "distance must be finite and >= 0, got {distance}"
            )));
        }
        let local = self.local_points(points)?;
        let stop = distance * distance;
        // Below `stop` a search ended early: within the distance. Else it ran to
        // completion, and `d2` is the exact minimum.
        let (order, verdicts) =
            self.search_coherent(&local, QUERY_CHUNK, stop, |hit| hit.d2 > stop);
        let mut far = vec![false; points.len()];
        for (&i, verdict) in order.iter().zip(verdicts) {
            far[i as usize] = verdict;
        }
        Ok(far)
    }

    /// `points` (caller's frame) in the tree's recentred frame, checked: finite and
    /// within [`MAX_EXTENT`] of the centre. Fails on an empty tree.
    fn local_points(&self, points: &[[f64; 3]]) -> Result<Vec<DVec3>, MeshError> {
        if self.is_empty() {
            return Err(MeshError::Empty("the tree holds no triangles".into()));
        }
        check_finite(points).map_err(|e| match e {
            MeshError::NonFinite { vertex } => {
                MeshError::Parameter(format!("point {vertex} has a NaN or infinite coordinate"))
            }
            other => other,
        })?;
        let local: Vec<DVec3> = points
            .par_iter()
            .map(|p| DVec3::from_array(*p) - self.centre)
            .collect();
        if let Some((i, far)) = self.beyond_reach(&local) {
            return Err(MeshError::Parameter(format!(
                "point {i} lies {far:.3e} (length) from the mesh's centre: more than the \
                 supported {MAX_EXTENT:.0e}"
            )));
        }
        Ok(local)
    }
}
