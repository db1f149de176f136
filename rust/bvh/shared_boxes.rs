//! Triangles whose f32 boxes are bitwise equal, grouped before the PLOC build (see
//! *Equal boxes* in the [module docs](super)): a radix sort of 32-bit box hashes, and
//! nothing more unless two hashes are equal.

use obvhs::aabb::Aabb;
use rayon::prelude::*;

/// The bit patterns of a triangle's three recentred corners.
type CornerBits = [[u64; 3]; 3];

/// Triangles whose f32 boxes are bitwise equal, found before the PLOC build: PLOC gets
/// each box once. Given `n` equal boxes (a mesh collapsed to a point) it merged one pair
/// per pass, a chain `n` deep built in quadratic time (69k faces: 15 s).
#[derive(Debug)]
pub(super) struct SharedBoxes {
    /// The distinct boxes, in the order of their smallest face: obvhs's primitives.
    pub(super) boxes: Vec<Aabb>,
    /// Per distinct box, its face when it holds one, else [`SHARED`] `| g`, `g` its entry
    /// in `groups`.
    pub(super) entry: Vec<u32>,
    /// Per box of several faces, its range of `item_start` (one entry more).
    pub(super) groups: Vec<u32>,
    /// Per item (a set of bitwise-identical triangles), its range of `faces` (one more).
    pub(super) item_start: Vec<u32>,
    /// Faces, in face order inside an item; a box's items in the order of their first face.
    pub(super) faces: Vec<u32>,
}

/// Flag of a [`SharedBoxes`] entry: a box of several faces.
pub(super) const SHARED: u32 = 1 << 31;

impl SharedBoxes {
    /// Groups the faces by box; inside a box, by `key` (bitwise corners: identical
    /// triangles). None when every box is distinct (the usual case).
    pub(super) fn find(boxes: &[Aabb], key: impl Fn(u32) -> CornerBits) -> Option<SharedBoxes> {
        let bits = |b: &Aabb| {
            let (lo, hi) = (b.min.to_array(), b.max.to_array());
            [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
        };
        // 32-bit hashes of the boxes above the face indices, sorted by hash (stable: equal
        // hashes in face order). Equal boxes have equal hashes; equal hashes are checked.
        let mut keyed: Vec<u64> = boxes
            .par_iter()
            .enumerate()
            .map(|(i, b)| {
                let h = bits(b).iter().fold(0u64, |h, &x| {
                    (h ^ u64::from(x)).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                });
                (h & !0xffff_ffff) | i as u64
            })
            .collect();
        radix_sort_high32(&mut keyed);
        let hash = |k: &u64| k >> 32;
        if !keyed.par_windows(2).any(|w| hash(&w[0]) == hash(&w[1])) {
            return None;
        }
        // The faces of each box held by several, in face order.
        let mut several: Vec<Vec<u32>> = Vec::new();
        let mut run = Vec::new();
        for same_hash in keyed
            .chunk_by(|a, b| hash(a) == hash(b))
            .filter(|r| r.len() > 1)
        {
            run.clear();
            run.extend(same_hash.iter().map(|&k| {
                let face = k as u32;
                (bits(&boxes[face as usize]), face)
            }));
            run.sort_unstable();
            for same_box in run.chunk_by(|a, b| a.0 == b.0).filter(|r| r.len() > 1) {
                several.push(same_box.iter().map(|&(_, face)| face).collect());
            }
        }
        if several.is_empty() {
            return None;
        }
        several.sort_unstable_by_key(|faces| faces[0]);
        // A face stands for its box when no smaller face shares it.
        let mut hidden = vec![false; boxes.len()];
        for faces in &several {
            for &face in &faces[1..] {
                hidden[face as usize] = true;
            }
        }
        let distinct: Vec<u32> = (0..boxes.len() as u32)
            .into_par_iter()
            .filter(|&face| !hidden[face as usize])
            .collect();
        // Where each box of several faces stands among the distinct ones.
        let at: Vec<usize> = several
            .iter()
            .map(|faces| distinct.binary_search(&faces[0]).expect("a distinct face"))
            .collect();
        let mut shared = SharedBoxes {
            boxes: distinct.par_iter().map(|&f| boxes[f as usize]).collect(),
            entry: distinct,
            groups: Vec::with_capacity(several.len() + 1),
            item_start: Vec::new(),
            faces: Vec::new(),
        };
        // Inside each box, identical triangles together (each item in face order), the
        // items in the order of their first face.
        let mut by_key = Vec::new();
        for (g, faces) in several.iter().enumerate() {
            shared.entry[at[g]] = SHARED | g as u32;
            shared.groups.push(shared.item_start.len() as u32);
            by_key.clear();
            by_key.extend(faces.iter().map(|&f| (key(f), f)));
            by_key.sort_unstable();
            let mut items: Vec<&[(CornerBits, u32)]> = by_key.chunk_by(|a, b| a.0 == b.0).collect();
            items.sort_unstable_by_key(|item| item[0].1);
            for item in items {
                shared.item_start.push(shared.faces.len() as u32);
                shared.faces.extend(item.iter().map(|&(_, f)| f));
            }
        }
        shared.groups.push(shared.item_start.len() as u32);
        shared.item_start.push(shared.faces.len() as u32);
        Some(shared)
    }

    /// The faces of item `item`.
    pub(super) fn item(&self, item: u32) -> &[u32] {
        let (a, b) = (
            self.item_start[item as usize],
            self.item_start[item as usize + 1],
        );
        &self.faces[a as usize..b as usize]
    }
}

/// `keys` sorted by their upper 32 bits, stably (LSD radix sort, four 8-bit passes).
fn radix_sort_high32(keys: &mut Vec<u64>) {
    let mut other = vec![0u64; keys.len()];
    for pass in 0..4 {
        let shift = 32 + 8 * pass;
        let digit = |k: u64| ((k >> shift) & 0xff) as usize;
        let mut start = [0usize; 257];
        for &k in keys.iter() {
            start[digit(k) + 1] += 1;
        }
        for i in 0..256 {
            start[i + 1] += start[i];
        }
        for &k in keys.iter() {
            let at = &mut start[digit(k)];
            other[*at] = k;
            *at += 1;
        }
        std::mem::swap(keys, &mut other);
    }
}
