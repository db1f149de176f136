//! What the PLOC builder builds on: the faces outside collinear runs (through
//! [`SharedBoxes`] when some of their boxes are bitwise equal), then one box per run (see
//! *Equal boxes* and *Collinear runs* in the [module docs](super)).

use obvhs::aabb::Aabb;

use super::runs::FoundRun;
use super::shared_boxes::{SHARED, SharedBoxes};

/// What obvhs builds on: the faces outside runs (through [`SharedBoxes`] when some boxes
/// are equal), then one box per run.
pub(super) struct Primitives {
    /// The faces outside runs, when there are runs (else every face).
    plain: Option<Vec<u32>>,
    shared: Option<SharedBoxes>,
    runs: Vec<FoundRun>,
    /// The boxes, when there are runs.
    boxes: Option<Vec<Aabb>>,
}

/// One of obvhs's primitives.
pub(super) enum Primitive<'a> {
    Face(u32),
    /// Shared boxes and the group `g` of several faces.
    Shared(&'a SharedBoxes, usize),
    Run(&'a FoundRun),
}

impl Primitives {
    /// The primitives of `faces` (boxes `boxes`, per face) given their `runs`; `key` as
    /// in [`SharedBoxes::find`].
    pub(super) fn new(
        faces: &[[u32; 3]],
        boxes: &[Aabb],
        runs: Vec<FoundRun>,
        key: impl Fn(u32) -> [[u64; 3]; 3],
    ) -> Self {
        if runs.is_empty() {
            return Primitives {
                plain: None,
                shared: SharedBoxes::find(boxes, key),
                runs,
                boxes: None,
            };
        }
        let mut in_run = vec![false; faces.len()];
        for run in &runs {
            for &f in &run.faces {
                in_run[f as usize] = true;
            }
        }
        let plain: Vec<u32> = (0..faces.len() as u32)
            .filter(|&f| !in_run[f as usize])
            .collect();
        let plain_boxes: Vec<Aabb> = plain.iter().map(|&f| boxes[f as usize]).collect();
        let mut shared = SharedBoxes::find(&plain_boxes, |i| key(plain[i as usize]));
        if let Some(shared) = &mut shared {
            // From indices into `plain` to faces (increasing either way).
            for e in shared.entry.iter_mut().filter(|e| **e & SHARED == 0) {
                *e = plain[*e as usize];
            }
            for f in &mut shared.faces {
                *f = plain[*f as usize];
            }
        }
        let mut all = match &shared {
            Some(shared) => shared.boxes.clone(),
            None => plain_boxes,
        };
        all.extend(runs.iter().map(|r| r.aabb));
        Primitives {
            plain: Some(plain),
            shared,
            runs,
            boxes: Some(all),
        }
    }

    /// The boxes obvhs builds on (`faces`: every face's).
    pub(super) fn boxes<'a>(&'a self, faces: &'a [Aabb]) -> &'a [Aabb] {
        match (&self.boxes, &self.shared) {
            (Some(boxes), _) => boxes,
            (None, Some(shared)) => &shared.boxes,
            (None, None) => faces,
        }
    }

    /// What obvhs's primitive `b` stands for.
    pub(super) fn kind(&self, b: u32) -> Primitive<'_> {
        let b = b as usize;
        let before_runs = match (&self.shared, &self.plain) {
            (Some(shared), _) => shared.entry.len(),
            (None, Some(plain)) => plain.len(),
            (None, None) => usize::MAX,
        };
        if b >= before_runs {
            return Primitive::Run(&self.runs[b - before_runs]);
        }
        match (&self.shared, &self.plain) {
            (Some(shared), _) => {
                let entry = shared.entry[b];
                if entry & SHARED == 0 {
                    Primitive::Face(entry)
                } else {
                    Primitive::Shared(shared, (entry & !SHARED) as usize)
                }
            }
            (None, Some(plain)) => Primitive::Face(plain[b]),
            (None, None) => Primitive::Face(b as u32),
        }
    }
}
