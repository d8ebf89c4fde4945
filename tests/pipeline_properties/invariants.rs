//! The invariants `pipeline_properties` checks after every step: what a
//! pipeline at rest must hold, a session's round trip, and what localise
//! mode must leave as mapping built it.

use std::io::Cursor;
use surfel_slam::pipeline::VerdictCounts;
use surfel_slam::session;
use surfel_slam::{FrameReport, Pipeline};

/// What the test knows the pipeline must hold.
#[derive(Default)]
pub struct Model {
    /// Timestamps of the frames accepted since the last reset.
    pub accepted: Vec<f64>,
    pub last_report: Option<FrameReport>,
}

/// Every invariant of a pipeline at rest.
pub fn check(slam: &Pipeline, model: &Model, at: &dyn Fn(&str) -> String) {
    let map = slam.map();
    let n = map.len();
    let lens = [
        map.positions().len(),
        map.normals().len(),
        map.colours().len(),
        map.radii().len(),
        map.confidences().len(),
        map.first_seen().len(),
        map.last_seen().len(),
    ];
    assert!(
        lens.iter().all(|&l| l == n),
        "{}",
        at(&format!("array lengths {lens:?}"))
    );
    assert!(map.all_finite(), "{}", at("a NaN or infinity in the map"));
    let live = map.confidences().iter().filter(|&&c| c >= 0.0).count();
    assert_eq!(map.live_len(), live, "{}", at("live surfels"));
    assert_eq!(
        map.live_len() + map.absorbed_len(),
        n,
        "{}",
        at("live + absorbed")
    );
    assert!(
        n <= slam.config().fusion.max_surfels,
        "{}",
        at("over the budget")
    );
    // Times in the map: created no later than last updated, and both at a
    // frame pushed since the last reset (the current one is frames - 1).
    let frames = slam.frames();
    for (i, (&first, &last)) in map.first_seen().iter().zip(map.last_seen()).enumerate() {
        assert!(
            first <= last && last < frames,
            "{}",
            at(&format!(
                "surfel {i}: first_seen {first}, last_seen {last}, {frames} frames"
            ))
        );
    }
    let c = slam.counts();
    let frames = slam.frames() as usize;
    assert_eq!(frames, model.accepted.len(), "{}", at("frames accepted"));
    assert_eq!(
        (c.tracked + c.lost + c.recovered + c.held + c.restarted) as usize,
        frames,
        "{}",
        at(&format!("verdict counts {c:?}"))
    );
    assert!(c.lost_streak <= c.lost, "{}", at("lost streak"));
    let trajectory = slam.trajectory();
    assert_eq!(trajectory.len(), frames, "{}", at("trajectory length"));
    assert_eq!(
        slam.online_trajectory().len(),
        frames,
        "{}",
        at("online trajectory length")
    );
    assert!(
        trajectory
            .iter()
            .zip(&model.accepted)
            .all(|((t, pose), &pushed)| *t == pushed && pose.is_finite()),
        "{}",
        at("trajectory timestamps or poses")
    );
    match &model.last_report {
        Some(r) => {
            assert_eq!(r.index as usize + 1, frames, "{}", at("report index"));
            assert_eq!(r.surfels, map.live_len(), "{}", at("report surfels"));
            assert_eq!(r.surfel_slots, n, "{}", at("report slots"));
            assert_eq!(r.counts, c, "{}", at("report counts"));
            assert!(r.world_from_camera.is_finite(), "{}", at("report pose"));
        }
        None => assert_eq!(frames, 0, "{}", at("frames without a report")),
    }
}

/// Saves `slam` as a session; a cut copy is refused and changes nothing;
/// the whole one loads into a pipeline holding the same trajectory and
/// map, which carries on in place of `slam`.
pub fn session_round_trip(slam: &mut Pipeline, at: &dyn Fn(&str) -> String) {
    let bytes = session::save(slam, Cursor::new(Vec::new()))
        .map(Cursor::into_inner)
        .unwrap_or_else(|e| panic!("{}", at(&format!("session not saved: {e}"))));
    let before = (slam.frames(), slam.map().len(), slam.counts());
    let cut = session::load_into(slam, Cursor::new(&bytes[..bytes.len() / 2]));
    assert!(cut.is_err(), "{}", at("a cut session loaded"));
    let after = (slam.frames(), slam.map().len(), slam.counts());
    assert_eq!(
        before,
        after,
        "{}",
        at("a cut session changed the pipeline")
    );
    let loaded = session::load(Cursor::new(&bytes))
        .unwrap_or_else(|e| panic!("{}", at(&format!("session not loaded: {e}"))));
    assert_eq!(
        loaded.trajectory(),
        slam.trajectory(),
        "{}",
        at("loaded trajectory")
    );
    assert_eq!(
        loaded.map().positions(),
        slam.map().positions(),
        "{}",
        at("loaded map")
    );
    assert_eq!(loaded.counts(), slam.counts(), "{}", at("loaded counts"));
    *slam = loaded;
}

/// What mapping built, which localise mode must leave as it is.
#[derive(Debug, PartialEq)]
pub struct Mapped {
    frames: u32,
    counts: VerdictCounts,
    slots: usize,
    live: usize,
    /// Bits of every surfel position.
    positions: Vec<[u32; 3]>,
}

impl Mapped {
    pub fn of(slam: &Pipeline) -> Self {
        Self {
            frames: slam.frames(),
            counts: slam.counts(),
            slots: slam.map().len(),
            live: slam.map().live_len(),
            positions: slam
                .map()
                .positions()
                .iter()
                .map(|p| p.to_array().map(f32::to_bits))
                .collect(),
        }
    }
}
