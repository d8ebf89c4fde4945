//! A run's state as bits (both trajectories and every surfel array), for
//! tests that require two runs to agree exactly.

use glam::DAffine3;
use surfel_slam::Pipeline;

/// Both trajectories and every surfel array of a pipeline, as bits.
#[derive(PartialEq, Eq, Debug)]
pub struct RunBits {
    pub trajectory: Vec<[u64; 13]>,
    pub online_trajectory: Vec<[u64; 13]>,
    pub positions: Vec<[u32; 3]>,
    pub normals: Vec<[u32; 3]>,
    pub colours: Vec<[u8; 4]>,
    pub radii: Vec<u32>,
    pub confidences: Vec<u32>,
    pub first_seen: Vec<u32>,
    pub last_seen: Vec<u32>,
}

/// A trajectory entry's timestamp and pose columns as bits.
pub fn pose_bits((t, pose): &(f64, DAffine3)) -> [u64; 13] {
    let mut out = [t.to_bits(); 13];
    for (o, v) in out[1..].iter_mut().zip(pose.to_cols_array()) {
        *o = v.to_bits();
    }
    out
}

/// Where two lists first differ, if they do.
pub fn first_difference<T: PartialEq + std::fmt::Debug>(
    name: &str,
    a: &[T],
    b: &[T],
) -> Option<String> {
    if a.len() != b.len() {
        return Some(format!("{name}: {} vs {} entries", a.len(), b.len()));
    }
    let i = a.iter().zip(b).position(|(x, y)| x != y)?;
    Some(format!("{name}[{i}]: {:?} vs {:?}", a[i], b[i]))
}

impl RunBits {
    /// The state of `slam` now.
    pub fn of(slam: &Pipeline) -> Self {
        let map = slam.map();
        let v3 = |v: &glam::Vec3| v.to_array().map(f32::to_bits);
        Self {
            trajectory: slam.trajectory().iter().map(pose_bits).collect(),
            online_trajectory: slam.online_trajectory().iter().map(pose_bits).collect(),
            positions: map.positions().iter().map(v3).collect(),
            normals: map.normals().iter().map(v3).collect(),
            colours: map.colours().to_vec(),
            radii: map.radii().iter().map(|r| r.to_bits()).collect(),
            confidences: map.confidences().iter().map(|c| c.to_bits()).collect(),
            first_seen: map.first_seen().to_vec(),
            last_seen: map.last_seen().to_vec(),
        }
    }

    /// The first difference of each part, one line each (empty: the same bits).
    pub fn differences(&self, other: &Self) -> Vec<String> {
        let (a, b) = (self, other);
        [
            first_difference("trajectory", &a.trajectory, &b.trajectory),
            first_difference(
                "online trajectory",
                &a.online_trajectory,
                &b.online_trajectory,
            ),
            first_difference("positions", &a.positions, &b.positions),
            first_difference("normals", &a.normals, &b.normals),
            first_difference("colours", &a.colours, &b.colours),
            first_difference("radii", &a.radii, &b.radii),
            first_difference("confidences", &a.confidences, &b.confidences),
            first_difference("first_seen", &a.first_seen, &b.first_seen),
            first_difference("last_seen", &a.last_seen, &b.last_seen),
        ]
        .into_iter()
        .flatten()
        .collect()
    }
}
