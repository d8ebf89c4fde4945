//! Robustness: adversarial frames and settings never poison the map or the
//! pose, lost frames are not fused, tracking is re-acquired after a loss, and
//! the surfel budget holds.
//!
//! The real-data test (TUM fr3/teddy with dropped frames, blank frames and a
//! frame of ICL-NUIM spliced in) reads ../shared/data and skips with a
//! message when it is absent; the synthetic ones always run.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{shared_dataset, synthetic_config};
use glam::DAffine3;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::ate;
use surfel_slam::se3::motion_magnitude;
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::{
    FrameError, Intrinsics, Pipeline, PipelineError, RgbdFrame, SlamConfig, Verdict,
};

fn small_intrinsics() -> Intrinsics {
    synthetic::default_intrinsics().half()
}

fn assert_sane(slam: &Pipeline) {
    assert!(slam.map().all_finite(), "a NaN or infinity entered the map");
    assert!(
        slam.trajectory().iter().all(|(_, p)| p.is_finite()),
        "a NaN or infinity entered the trajectory"
    );
}

/// Renders synthetic trajectory frame `i` (noise-free unless `noise`).
fn render(k: &Intrinsics, config: &SlamConfig, i: usize, noise: &NoiseModel) -> RgbdFrame {
    synthetic::render(
        &Scene::room(),
        k,
        &synthetic::trajectory_pose(i),
        noise,
        i as u64,
    )
    .to_frame(&config.depth)
    .expect("synthetic frame")
}

#[test]
fn non_finite_and_absurd_settings_are_refused_by_name() {
    let good = synthetic_config(small_intrinsics());
    let refuse = |config: SlamConfig, needle: &str| {
        let err = Pipeline::new(config).expect_err("refused");
        assert!(err.to_string().contains(needle), "{needle}: {err}");
    };
    let mut c = good.clone();
    c.intrinsics.fx = f32::NAN;
    refuse(c, "fx");
    let mut c = good.clone();
    c.intrinsics.cy = f32::NEG_INFINITY;
    refuse(c, "cy");
    let mut c = good.clone();
    c.intrinsics.fy = 0.5; // metres typed for pixels
    refuse(c, "fy");
    let mut c = good.clone();
    c.depth.scale = 0.0;
    refuse(c, "depth scale");
    let mut c = good.clone();
    c.depth.scale = f32::NAN;
    refuse(c, "depth scale");
    let mut c = good.clone();
    c.depth.max_m = c.depth.min_m;
    refuse(c, "depth range");
}

#[test]
fn hostile_frames_are_refused_and_spikes_never_poison_the_map() {
    let k = small_intrinsics();
    let config = synthetic_config(k);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let noise = NoiseModel::kinect();
    for i in 0..4 {
        slam.push_frame(&render(&k, &config, i, &noise), i as f64)
            .expect("push");
    }
    let surfels = slam.map().len();

    // Built by hand with NaN, infinite or negative depth: refused, map untouched.
    for bad in [f32::NAN, f32::INFINITY, -1.0] {
        let mut f = render(&k, &config, 4, &noise);
        f.depth_m[123] = bad;
        let err = slam.push_frame(&f, 4.0).expect_err("refused");
        assert!(
            matches!(
                err,
                PipelineError::Frame(FrameError::InvalidDepth { pixel: 123, .. })
            ),
            "{err}"
        );
    }
    // Buffers shorter than the size claims: refused, no panic.
    let mut f = render(&k, &config, 4, &noise);
    f.rgb.truncate(10);
    assert!(slam.push_frame(&f, 4.0).is_err());
    let mut f = render(&k, &config, 4, &noise);
    f.depth_m.pop();
    assert!(slam.push_frame(&f, 4.0).is_err());
    // A depth deviation map of the wrong length, or holding a multiplier
    // below 1 or NaN: refused by name.
    let mut f = render(&k, &config, 4, &noise);
    f.depth_deviation = vec![1.0; f.depth_m.len() - 1];
    assert!(matches!(
        slam.push_frame(&f, 4.0),
        Err(PipelineError::Frame(FrameError::BufferLength { .. }))
    ));
    for bad in [f32::NAN, 0.5, f32::INFINITY] {
        f.depth_deviation = vec![1.0; f.depth_m.len()];
        f.depth_deviation[77] = bad;
        assert!(matches!(
            slam.push_frame(&f, 4.0),
            Err(PipelineError::Frame(FrameError::InvalidDepthDeviation {
                pixel: 77,
                ..
            }))
        ));
    }
    // A frame of another size: refused.
    let other = render(&k.half(), &config, 4, &noise);
    assert!(matches!(
        slam.push_frame(&other, 4.0),
        Err(PipelineError::Frame(FrameError::UnexpectedSize { .. }))
    ));
    assert_eq!(slam.map().len(), surfels, "refused frames changed the map");
    assert_sane(&slam);

    // Spikes: every 7th pixel at the near or far limit of the range, and
    // a dense patch of 1 cm depths (clipped to 0 by the range) on top.
    for i in 4..20 {
        let mut f = render(&k, &config, i, &noise);
        // Every other frame marks a third of its pixels as uncertain as a
        // finite multiplier can.
        if i % 2 == 0 {
            f.depth_deviation = (0..f.depth_m.len())
                .map(|j| if j % 3 == 0 { f32::MAX } else { 1.0 })
                .collect();
        }
        for (j, d) in f.depth_m.iter_mut().enumerate() {
            if j % 7 == i % 7 {
                *d = if j % 2 == 0 {
                    config.depth.min_m
                } else {
                    config.depth.max_m
                };
            }
        }
        let r = slam.push_frame(&f, i as f64).expect("push");
        assert!(r.world_from_camera.is_finite());
        assert_sane(&slam);
    }
    assert!(slam.map().len() >= surfels, "the map collapsed");
    assert_sane(&slam);
}

#[test]
fn blank_frames_are_lost_then_tracking_is_reacquired_or_refused_never_wrong() {
    let k = small_intrinsics();
    let config = synthetic_config(k);
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let none = NoiseModel::none();
    // The pipeline's world is the first camera's frame.
    let world_from_first = synthetic::trajectory_pose(0);
    let truth = |i: usize| world_from_first.inverse() * synthetic::trajectory_pose(i);
    let push = |slam: &mut Pipeline, i: usize, blank: bool| {
        let mut f = render(&k, &config, i, &none);
        if blank {
            f.depth_m.iter_mut().for_each(|d| *d = 0.0);
        }
        slam.push_frame(&f, i as f64).expect("push")
    };
    for i in 0..4 {
        push(&mut slam, i, false);
    }
    // Blank frames: lost, the map and the pose untouched, while the camera moves on.
    for blanks in [4..7, 12..15] {
        let surfels = slam.map().len();
        let held = slam.trajectory().last().expect("pose").1;
        for i in blanks.clone() {
            let r = push(&mut slam, i, true);
            assert!(matches!(r.verdict, Verdict::Lost(_)), "{:?}", r.verdict);
            assert_eq!(r.world_from_camera, held, "the pose is held");
            assert_eq!(slam.map().len(), surfels, "a lost frame was fused");
        }
        assert_eq!(slam.counts().lost_streak, 3);
        for i in blanks.end..blanks.end + 5 {
            let r = push(&mut slam, i, false);
            if i == 7 {
                // A well-conditioned view: re-acquired at once.
                assert_eq!(r.verdict, Verdict::Recovered);
            }
            // Re-acquired, or refused (a view that does not pin the pose):
            // never fused at a wrong pose.
            if r.verdict.is_fused() {
                let (dt, dr) = motion_magnitude(&(truth(i).inverse() * r.world_from_camera));
                assert!(
                    dt < 0.01 && dr.to_degrees() < 0.5,
                    "frame {i} {:?}: {dt} m, {dr} rad",
                    r.verdict
                );
            }
        }
        assert_sane(&slam);
    }
    let counts = slam.counts();
    eprintln!("synthetic blank frames: {counts:?}");
    assert!(counts.recovered >= 1 && counts.lost >= 6, "{counts:?}");
}

#[test]
fn the_surfel_budget_holds_and_tracking_goes_on() {
    let k = small_intrinsics();
    let mut config = synthetic_config(k);
    config.fusion.max_surfels = 60_000; // less than one 320x240 frame
    let mut slam = Pipeline::new(config.clone()).expect("config");
    let mut skipped = 0;
    for i in 0..40 {
        let r = slam
            .push_frame(&render(&k, &config, i, &NoiseModel::kinect()), i as f64)
            .expect("push");
        // The budget bounds the arrays: surfels plus absorbed ones awaiting compaction.
        assert!(
            r.surfels <= r.surfel_slots && r.surfel_slots <= config.fusion.max_surfels,
            "{} surfels, {} slots",
            r.surfels,
            r.surfel_slots
        );
        assert!(r.verdict.is_fused(), "frame {i}: {:?}", r.verdict);
        skipped += r.fusion.skipped;
    }
    assert!(
        skipped > 0,
        "the budget was never reached: the test proves nothing"
    );
    assert_sane(&slam);
}

/// One item of the adversarial real-data stream.
enum Item {
    Teddy(usize),
    BlankTeddy(usize),
    Icl(usize),
}

#[test]
fn tum_teddy_with_dropped_blank_and_foreign_frames() {
    let (Some(teddy_dir), Some(icl_dir)) = (
        shared_dataset("tum_fr3_teddy"),
        shared_dataset("icl_office_kt0"),
    ) else {
        return;
    };
    let teddy = Sequence::open(&teddy_dir).expect("teddy");
    let icl = Sequence::open(&icl_dir).expect("icl");
    let config = SlamConfig::from_preset(teddy.preset);
    let mut slam = Pipeline::new(config.clone()).expect("config");

    // 0..40 at full rate, 40..120 keeping every 5th frame, two blank frames,
    // an ICL-NUIM frame, one more blank, then 131..193 at full rate: the
    // camera moved on by several frames while the input was useless.
    let mut stream: Vec<Item> = (0..40).map(Item::Teddy).collect();
    stream.extend((40..120).step_by(5).map(Item::Teddy));
    stream.extend([
        Item::BlankTeddy(121),
        Item::BlankTeddy(122),
        Item::Icl(30),
        Item::BlankTeddy(124),
    ]);
    stream.extend((131..teddy.frames.len()).map(Item::Teddy));

    let mut verdicts = Vec::new();
    let mut surfels_before_bad = 0;
    let mut stable_before_bad = 0;
    let stable = |slam: &Pipeline| {
        let c = slam.config().fusion.stable_confidence;
        slam.map().confidences().iter().filter(|&&x| x >= c).count()
    };
    for item in &stream {
        let (frame, t, bad) = match *item {
            Item::Teddy(i) => {
                let e = &teddy.frames[i];
                (
                    read_frame(&teddy_dir, e, &config.depth).expect("teddy frame"),
                    e.timestamp,
                    false,
                )
            }
            Item::BlankTeddy(i) => {
                let e = &teddy.frames[i];
                let mut f = read_frame(&teddy_dir, e, &config.depth).expect("teddy frame");
                f.depth_m.iter_mut().for_each(|d| *d = 0.0);
                (f, e.timestamp, true)
            }
            Item::Icl(i) => {
                let f = read_frame(&icl_dir, &icl.frames[i], &icl.preset.depth_settings())
                    .expect("icl frame");
                // Stamped between two teddy frames so that it has no ground truth.
                (f, teddy.frames[123].timestamp, true)
            }
        };
        if bad && surfels_before_bad == 0 {
            surfels_before_bad = slam.map().len();
            stable_before_bad = stable(&slam);
        }
        let before = slam.map().len();
        let r = slam.push_frame(&frame, t).expect("accepted");
        if bad {
            assert!(
                matches!(r.verdict, Verdict::Lost(_)),
                "a blank or foreign frame was not judged lost: {r:?}"
            );
            assert_eq!(slam.map().len(), before, "a lost frame was fused");
        }
        assert_sane(&slam);
        verdicts.push((r.verdict, t, bad));
    }

    let counts = slam.counts();
    let fused: Vec<(f64, DAffine3)> = slam
        .trajectory()
        .iter()
        .zip(&verdicts)
        .filter(|(_, (v, _, _))| v.is_fused())
        .map(|(p, _)| *p)
        .collect();
    let a = ate(&fused, &teddy.ground_truth, 0.02).expect("ate");
    let last_bad = verdicts.iter().rposition(|v| v.2).expect("bad frames");
    let after: Vec<&Verdict> = verdicts[last_bad + 1..].iter().map(|v| &v.0).collect();
    let reacquired = after.iter().position(|v| v.is_fused());
    let bad_verdicts: Vec<&str> = verdicts
        .iter()
        .filter(|v| v.2)
        .map(|v| match v.0 {
            Verdict::Lost(reason) => reason.name(),
            other => other.name(),
        })
        .collect();
    eprintln!(
        "teddy with dropped/blank/foreign frames: {} frames pushed, {} tracked, {} lost, {} recovered; \
         bad frames (blank, blank, ICL-NUIM, blank): {bad_verdicts:?}; \
         re-acquired {:?} frames after the last bad one; {} of the last {} fused; \
         ATE {:.2} cm over {} fused poses; surfels {} ({} stable) before the bad frames, {} ({} stable) at the end",
        verdicts.len(),
        counts.tracked,
        counts.lost,
        counts.recovered,
        reacquired.map(|n| n + 1),
        after.iter().filter(|v| v.is_fused()).count(),
        after.len(),
        a.rmse_m * 100.0,
        a.pairs,
        surfels_before_bad,
        stable_before_bad,
        slam.map().len(),
        stable(&slam)
    );
    assert!(counts.lost >= 4, "the four bad frames are lost");
    assert!(counts.recovered >= 1, "tracking was re-acquired");
    assert!(
        reacquired.is_some_and(|n| n < 3),
        "re-acquired within 3 frames: {reacquired:?}"
    );
    let fused_after = after.iter().filter(|v| v.is_fused()).count();
    assert!(
        fused_after * 10 >= after.len() * 9,
        "tracking held after recovery"
    );
    // Unstable surfels come and go (noise, removed after 10 frames); the
    // stable ones are the map, and none may be lost.
    assert!(
        stable(&slam) >= stable_before_bad && slam.map().len() >= stable_before_bad,
        "the map collapsed: {} stable / {} surfels before the bad frames, {} / {} at the end",
        stable_before_bad,
        surfels_before_bad,
        stable(&slam),
        slam.map().len()
    );
    // The clean sequence runs at ~1 cm (tests/real_sequences.rs bounds it at
    // 2 cm); a wrong re-acquisition or a fused foreign frame shifts the rest
    // of the trajectory by decimetres. 3 cm allows the sparser segment.
    assert!(a.rmse_m <= 0.03, "ATE {} m", a.rmse_m);
}
