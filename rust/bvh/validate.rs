//! The tree's invariants, checked by [`TriangleTree::validate`] (the tests call it on
//! every tree they build): every triangle slot in exactly one leaf, inside its leaf's box;
//! every child box inside its parent's; the links and smallest face indices consistent;
//! the face map a permutation.

use glam::DVec3;

use super::tree::{IDENTICAL, RUN, TriangleTree, slots_of};

/// Whether `p` lies in the box `[min, max]` (compared in f64).
fn inside(min: &[f32; 3], max: &[f32; 3], p: DVec3) -> bool {
    (0..3).all(|k| min[k] as f64 <= p[k] && p[k] <= max[k] as f64)
}

impl TriangleTree {
    /// Checks the tree's invariants: every triangle slot sits in exactly one leaf, every
    /// triangle lies inside its leaf's box (in f64, margin `pad` included), every child
    /// box lies inside its parent's box, and the face map is a permutation.
    pub fn validate(&self) -> Result<(), String> {
        self.check_lengths_and_faces()?;
        let n = self.triangles.len();
        if n == 0 {
            return if self.pairs.is_empty() {
                Ok(())
            } else {
                Err("empty tree with nodes".into())
            };
        }
        let mut seen_slot = vec![false; n];
        if self.root_count > 0 {
            self.check_leaf(
                self.root_link,
                self.root_count,
                &self.root_min,
                &self.root_max,
                &mut seen_slot,
            )?;
            if self.leaf_pair.iter().any(|&p| p != u32::MAX) {
                return Err("a slot of the root leaf linked to a pair".into());
            }
        } else {
            self.check_pairs(&mut seen_slot)?;
        }
        match seen_slot.iter().position(|s| !s) {
            Some(slot) => Err(format!("triangle slot {slot} unreachable")),
            None => Ok(()),
        }
    }

    /// One face index and one leaf link per triangle, one parent link per pair, and the
    /// face map a permutation.
    fn check_lengths_and_faces(&self) -> Result<(), String> {
        let n = self.triangles.len();
        if self.faces.len() != n || self.leaf_pair.len() != n {
            return Err(format!(
                "{} faces and {} leaf links for {n} triangles",
                self.faces.len(),
                self.leaf_pair.len()
            ));
        }
        if self.parent.len() != self.pairs.len() {
            return Err(format!(
                "{} parent links for {} pairs",
                self.parent.len(),
                self.pairs.len()
            ));
        }
        let mut seen_face = vec![false; n];
        for &f in &self.faces {
            let slot = seen_face
                .get_mut(f as usize)
                .ok_or(format!("face {f} out of range"))?;
            if std::mem::replace(slot, true) {
                return Err(format!("face {f} stored twice"));
            }
        }
        Ok(())
    }

    /// The leaf `first`, `count` (flag included) in the box `[min, max]`: in range, its
    /// slots seen for the first time (marked in `seen_slot`), its corners inside the box,
    /// and, flagged [`IDENTICAL`], two or more identical triangles in face order; flagged
    /// [`RUN`], exactly the slots of one run, in face order, its table consistent.
    fn check_leaf(
        &self,
        first: u32,
        count: u32,
        min: &[f32; 3],
        max: &[f32; 3],
        seen_slot: &mut [bool],
    ) -> Result<(), String> {
        let n = self.triangles.len();
        let (flagged, run, count) = (count & IDENTICAL != 0, count & RUN != 0, slots_of(count));
        if count == 0 || (first + count) as usize > n || (flagged && run) {
            return Err(format!(
                "leaf {first}+{count} out of range or flagged twice"
            ));
        }
        let slots = first as usize..(first + count) as usize;
        match self.run_holding(first) {
            Some(r) if run => {
                r.check()?;
                if r.first != first || r.len != count || count < 2 {
                    return Err(format!("leaf {first}+{count} is not its run"));
                }
                if self.faces[slots.clone()].windows(2).any(|w| w[0] >= w[1]) {
                    return Err(format!("run leaf {first}+{count}: faces not increasing"));
                }
            }
            None if !run => {}
            _ => return Err(format!("leaf {first}+{count}: run flag and runs disagree")),
        }
        if flagged {
            let same = &self.triangles[first as usize];
            if count < 2
                || self.triangles[slots.clone()].iter().any(|t| t != same)
                || self.faces[slots].windows(2).any(|w| w[0] >= w[1])
            {
                return Err(format!(
                    "leaf {first}+{count} flagged identical: not 2 or more identical \
                     triangles in increasing face order"
                ));
            }
        }
        for slot in first..first + count {
            if std::mem::replace(&mut seen_slot[slot as usize], true) {
                return Err(format!("slot {slot} in two leaves"));
            }
            for corner in self.triangles[slot as usize].corners() {
                if !inside(min, max, corner) {
                    return Err(format!("slot {slot}: corner {corner} outside its box"));
                }
            }
        }
        Ok(())
    }

    /// Every pair reached once from the root pair, each child box inside its parent's,
    /// leaves checked ([`check_leaf`](Self::check_leaf)) and linked to their pair, inner
    /// children linked to their parent, and each child's smallest face index right.
    fn check_pairs(&self, seen_slot: &mut [bool]) -> Result<(), String> {
        if self.parent.get(self.root_link as usize) != Some(&u32::MAX) {
            return Err("the root pair has a parent".into());
        }
        if self.min_face.len() != 2 * self.pairs.len() {
            return Err(format!(
                "{} smallest faces for {} pairs",
                self.min_face.len(),
                self.pairs.len()
            ));
        }
        let mut seen_pair = vec![false; self.pairs.len()];
        let mut todo = vec![(self.root_link, self.root_min, self.root_max)];
        while let Some((index, pmin, pmax)) = todo.pop() {
            let pair = self
                .pairs
                .get(index as usize)
                .ok_or(format!("pair {index} missing"))?;
            if std::mem::replace(&mut seen_pair[index as usize], true) {
                return Err(format!("pair {index} reached twice"));
            }
            for k in 0..2 {
                let (min, max) = (pair.min[k], pair.max[k]);
                let corners = [
                    DVec3::from_array(min.map(f64::from)),
                    DVec3::from_array(max.map(f64::from)),
                ];
                if !corners.iter().all(|&c| inside(&pmin, &pmax, c)) {
                    return Err(format!("pair {index} child {k} outside its parent"));
                }
                let (link, count) = (pair.link[k], pair.count[k]);
                let smallest = if count > 0 {
                    self.check_leaf(link, count, &min, &max, seen_slot)?;
                    let slots = link as usize..(link + slots_of(count)) as usize;
                    if self.leaf_pair[slots.clone()].iter().any(|&p| p != index) {
                        return Err(format!("a slot of leaf {link} not linked to pair {index}"));
                    }
                    self.faces[slots].iter().copied().min()
                } else {
                    if self.parent.get(link as usize) != Some(&index) {
                        return Err(format!("pair {link} not linked to its parent {index}"));
                    }
                    todo.push((link, min, max));
                    let below = 2 * link as usize;
                    self.min_face.get(below..below + 2).map(|m| m[0].min(m[1]))
                };
                if smallest != Some(self.min_face[2 * index as usize + k]) {
                    return Err(format!("pair {index} child {k}: wrong smallest face"));
                }
            }
        }
        match seen_pair.iter().position(|s| !s) {
            Some(p) => Err(format!("pair {p} unreachable")),
            None => Ok(()),
        }
    }
}
