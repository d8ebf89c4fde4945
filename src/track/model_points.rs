//! ICP's source points: the pixels of a model prediction that hold a
//! surfel, packed row by row (world-frame vertex, normal, column).
//!
//! A prediction covers a part of the image (a third to nine tenths on the
//! real sequences), and tracking reads it a dozen times per frame. Packed
//! once per frame, each ICP pass reads only the pixels it uses instead of
//! every pixel's normal, and a strided pass reads a column number (4
//! bytes) for each point it skips instead of its vertex and normal.

use crate::camera::Intrinsics;
use crate::fusion::Prediction;
use glam::Vec3;
use rayon::prelude::*;

/// The prediction's pixels holding a surfel, row-major; see the module doc.
#[derive(Debug, Clone, Default)]
pub struct ModelPoints {
    /// Intrinsics of the prediction's view (`None`: nothing gathered).
    pub intrinsics: Option<Intrinsics>,
    /// Surfel centres, world frame, metres.
    vertices: Vec<Vec3>,
    /// Surfel normals, world frame, unit length.
    normals: Vec<Vec3>,
    /// Image column of each point.
    columns: Vec<u32>,
    /// Points of row `v` are `row_starts[v]..row_starts[v + 1]`.
    row_starts: Vec<usize>,
}

/// Rows filled by one task of [`ModelPoints::gather_from`].
const ROWS_PER_TASK: usize = 16;

impl ModelPoints {
    /// Packs the pixels of `prediction` that hold a surfel (non-zero
    /// normal), reusing the buffers.
    pub fn gather_from(&mut self, prediction: &Prediction) {
        self.intrinsics = None;
        self.row_starts.clear();
        let usable = prediction.intrinsics.filter(|k| {
            let n = k.width * k.height;
            k.width > 0 && prediction.normals.len() >= n && prediction.vertices.len() >= n
        });
        let Some(k) = usable else {
            self.vertices.clear();
            self.normals.clear();
            self.columns.clear();
            return;
        };
        let (w, h) = (k.width, k.height);
        let n = w * h;
        self.intrinsics = Some(k);
        let (vertices, normals) = (&prediction.vertices[..n], &prediction.normals[..n]);
        self.row_starts.resize(h + 1, 0);
        self.row_starts[1..]
            .par_iter_mut()
            .zip(normals.par_chunks(w))
            .for_each(|(count, row)| *count = row.iter().filter(|&&n| n != Vec3::ZERO).count());
        for v in 0..h {
            self.row_starts[v + 1] += self.row_starts[v];
        }
        let total = self.row_starts[h];
        // Every slot is written below: resized, not cleared, so that only
        // slots beyond the last frame's count are zeroed first.
        self.vertices.resize(total, Vec3::ZERO);
        self.normals.resize(total, Vec3::ZERO);
        self.columns.resize(total, 0);
        let out = Packed {
            vertices: &mut self.vertices,
            normals: &mut self.normals,
            columns: &mut self.columns,
        };
        fill_rows(0..h, out, &self.row_starts, (vertices, normals), w);
    }

    /// Number of points gathered.
    #[must_use]
    pub fn len(&self) -> usize {
        self.columns.len()
    }

    /// Whether no point was gathered.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// Columns, vertices and normals of the points of row `v` (empty past the last row).
    #[must_use]
    pub fn row(&self, v: usize) -> (&[u32], &[Vec3], &[Vec3]) {
        let (Some(&a), Some(&b)) = (self.row_starts.get(v), self.row_starts.get(v + 1)) else {
            return (&[], &[], &[]);
        };
        (
            &self.columns[a..b],
            &self.vertices[a..b],
            &self.normals[a..b],
        )
    }
}

/// The packed outputs of a range of rows.
struct Packed<'a> {
    vertices: &'a mut [Vec3],
    normals: &'a mut [Vec3],
    columns: &'a mut [u32],
}

/// Fills the points of `rows` into `out` (which starts at the first of
/// them), halving the rows between two tasks until a task has
/// [`ROWS_PER_TASK`]: uneven row lengths without a per-frame list of slices.
fn fill_rows(
    rows: std::ops::Range<usize>,
    out: Packed<'_>,
    row_starts: &[usize],
    (vertices, normals): (&[Vec3], &[Vec3]),
    w: usize,
) {
    if rows.len() > ROWS_PER_TASK {
        let mid = rows.start + rows.len() / 2;
        let split = row_starts[mid] - row_starts[rows.start];
        let (va, vb) = out.vertices.split_at_mut(split);
        let (na, nb) = out.normals.split_at_mut(split);
        let (ca, cb) = out.columns.split_at_mut(split);
        let first = Packed {
            vertices: va,
            normals: na,
            columns: ca,
        };
        let second = Packed {
            vertices: vb,
            normals: nb,
            columns: cb,
        };
        rayon::join(
            || fill_rows(rows.start..mid, first, row_starts, (vertices, normals), w),
            || fill_rows(mid..rows.end, second, row_starts, (vertices, normals), w),
        );
        return;
    }
    let mut at = 0;
    for v in rows {
        let base = v * w;
        for (u, (&p, &n)) in vertices[base..base + w]
            .iter()
            .zip(&normals[base..base + w])
            .enumerate()
        {
            if n != Vec3::ZERO {
                out.vertices[at] = p;
                out.normals[at] = n;
                out.columns[at] = u as u32;
                at += 1;
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn gathers_exactly_the_pixels_holding_a_surfel_in_row_order() {
        let k = Intrinsics::new(50.0, 50.0, 20.0, 15.0, 40, 70);
        let n = k.pixel_count();
        let holds = |i: usize| (i * 7919) % 5 < 2;
        let mut prediction = Prediction::new(false);
        prediction.intrinsics = Some(k);
        prediction.vertices = (0..n).map(|i| Vec3::new(i as f32, 1.0, 2.0)).collect();
        prediction.normals = (0..n)
            .map(|i| if holds(i) { Vec3::Z } else { Vec3::ZERO })
            .collect();
        let mut points = ModelPoints::default();
        points.gather_from(&prediction);
        assert_eq!(points.len(), (0..n).filter(|&i| holds(i)).count());
        for v in 0..k.height {
            let (columns, vertices, normals) = points.row(v);
            let expected: Vec<u32> = (0..k.width)
                .filter(|u| holds(v * k.width + u))
                .map(|u| u as u32)
                .collect();
            assert_eq!(columns, &expected[..], "row {v}");
            for ((&u, p), nrm) in columns.iter().zip(vertices).zip(normals) {
                assert_eq!(p.x, (v * k.width + u as usize) as f32);
                assert_eq!(*nrm, Vec3::Z);
            }
        }
        assert_eq!(points.row(k.height), (&[][..], &[][..], &[][..]));
        // An empty prediction gathers nothing, and buffers are reused.
        points.gather_from(&Prediction::new(false));
        assert!(points.is_empty() && points.intrinsics.is_none());
    }

    /// A wall at 2 m seen head-on by `k`: the model's points where `holds`
    /// (a pixel index) is true, and the frame's level seeing all of it.
    pub(crate) fn wall_model(
        k: &Intrinsics,
        holds: impl Fn(usize) -> bool,
    ) -> (ModelPoints, crate::preprocess::PyramidLevel) {
        let n = k.pixel_count();
        let wall: Vec<Vec3> = (0..n)
            .map(|i| k.back_project((i % k.width) as f32, (i / k.width) as f32, 2.0))
            .collect();
        let mut prediction = Prediction::new(false);
        prediction.intrinsics = Some(*k);
        prediction.vertices = wall.clone();
        prediction.normals = (0..n)
            .map(|i| if holds(i) { Vec3::NEG_Z } else { Vec3::ZERO })
            .collect();
        let target = crate::preprocess::PyramidLevel {
            intrinsics: Some(*k),
            depth: vec![2.0; n],
            vertices: wall,
            normals: vec![Vec3::NEG_Z; n],
            intensity: vec![0.0; n],
            depth_deviation: Vec::new(),
        };
        let mut points = ModelPoints::default();
        points.gather_from(&prediction);
        (points, target)
    }

    #[test]
    fn a_strided_icp_pass_uses_exactly_the_grid_pixels_holding_a_surfel() {
        use crate::se3::RigidF32;
        use crate::track::icp::{icp_step, IcpGates};
        // A wall at 2 m seen head-on; the model holds it with gaps.
        let k = Intrinsics::new(60.0, 60.0, 23.5, 17.5, 48, 36);
        let n = k.pixel_count();
        let holds = |i: usize| (i * 7919) % 7 < 4;
        let (points, target) = wall_model(&k, holds);
        let gates = IcpGates {
            distance_gate_m: 0.1,
            normal_gate_deg: 20.0,
            huber_m: 0.02,
        };
        let identity = RigidF32::from_affine(&glam::DAffine3::IDENTITY);
        for stride in 1..=5 {
            let step = icp_step(&points, stride, &target, &identity, &gates, None);
            let expected = (0..n)
                .filter(|&i| holds(i) && (i % k.width) % stride == 0 && (i / k.width) % stride == 0)
                .count();
            assert_eq!(step.candidates, expected, "stride {stride}");
            assert_eq!(step.system.count, expected, "stride {stride}");
        }
    }
}
