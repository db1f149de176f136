//! The order meshoptimizer's codecs compress best: triangles reordered for the vertex
//! cache, vertices renumbered in the order the triangles first use them.

use super::index_codec::check_triangle_list;
use crate::error::MeshError;

/// A triangle list reordered for the vertex cache, and its vertices renumbered in the
/// order the triangles first use them (meshoptimizer's `optimizeVertexCache`, then
/// first-use order as its `optimizeVertexFetchRemap`), the order its codecs compress best: returns the new
/// triangles and, for each new vertex, the old vertex it is. Unused vertices are dropped.
pub fn reorder_for_codecs(
    indices: &[u32],
    vertex_count: usize,
) -> Result<(Vec<u32>, Vec<u32>), MeshError> {
    check_triangle_list(indices, vertex_count)?;
    let cached = meshopt::optimize_vertex_cache(indices, vertex_count);
    // Vertices in the order of first use (meshoptimizer's fetch remap; the crate's
    // wrapper truncates the table it returns, so the loop is here).
    let mut new_of_old = vec![u32::MAX; vertex_count];
    let mut old_of_new = Vec::with_capacity(vertex_count);
    for &i in &cached {
        if new_of_old[i as usize] == u32::MAX {
            new_of_old[i as usize] = old_of_new.len() as u32;
            old_of_new.push(i);
        }
    }
    let triangles = cached.iter().map(|&i| new_of_old[i as usize]).collect();
    Ok((triangles, old_of_new))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reordering_keeps_the_triangles() {
        let indices: Vec<u32> = (0..600u32).map(|i| (i * 37) % 150).collect();
        let (triangles, old_of_new) = reorder_for_codecs(&indices, 160).unwrap();
        assert_eq!(old_of_new.len(), 150); // vertices 150..160 are unused
        let canonical = |t: [u32; 3]| {
            let k = (0..3).min_by_key(|&k| t[k]).unwrap();
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        };
        let mut before: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| canonical([t[0], t[1], t[2]]))
            .collect();
        let mut after: Vec<[u32; 3]> = triangles
            .chunks_exact(3)
            .map(|t| {
                canonical(
                    t.iter()
                        .map(|&i| old_of_new[i as usize])
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap(),
                )
            })
            .collect();
        before.sort_unstable();
        after.sort_unstable();
        assert_eq!(before, after);
    }
}
