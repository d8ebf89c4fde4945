//! Tracking where the geometry leaves a direction free (issue 50): the
//! long ICL-NUIM office (`../shared/data/icl_office_kt0_long`, every third
//! frame) around its frames 290-370, where the camera looks up at the
//! ceiling meeting a wall. Two planes leave the slide along their join
//! free; the ceiling tiles and lights pin it in colour.
//!
//! At the preset's defaults (the joint tracker), clean and with the
//! Kinect v1 recipe simulated (`SlamConfig::simulate_noise`), against the
//! exact truth: the ATE, and the motion of every frame called `tracked`
//! against the truth's. ICP alone on the same clean frames shows what the
//! colour term brings.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::truth_run::{run_frames, TruthRun};
use surfel_slam::dataset::Sequence;
use surfel_slam::simulated_noise::{NoiseSimulation, SimulatedSensor};
use surfel_slam::track::TrackerMode;
use surfel_slam::SlamConfig;

/// The frames of the ceiling-and-wall stretch.
const FIRST: usize = 290;
const COUNT: usize = 80;

/// Frames of the far view across the office (3-5 m), where the camera's
/// turn doubles at frames 92-93: with a constant bilateral range sigma the
/// Kinect-v1 terraces there posed as information and those frames slid
/// 2-2.7 cm along the x / yaw slide on every seed.
const FAR: std::ops::Range<usize> = 60..130;

fn run(sequence: &Sequence, dir: &std::path::Path, config: SlamConfig) -> TruthRun {
    run_frames(sequence, dir, config, FIRST..FIRST + COUNT)
}

#[test]
fn the_ceiling_meeting_a_wall_holds_clean_and_with_kinect_noise() {
    let Some(dir) = common::shared_dataset("icl_office_kt0_long") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence opens");
    let preset = SlamConfig::from_preset(sequence.preset);
    assert_eq!(preset.tracker.mode, TrackerMode::Joint);

    let clean = run(&sequence, &dir, preset.clone());
    let icp = run(
        &sequence,
        &dir,
        SlamConfig {
            tracker: surfel_slam::track::TrackerConfig {
                mode: TrackerMode::Icp,
                ..preset.tracker.clone()
            },
            ..preset.clone()
        },
    );
    let noisy = run(
        &sequence,
        &dir,
        SlamConfig {
            simulate_noise: Some(NoiseSimulation {
                sensor: SimulatedSensor::KinectV1,
                seed: 1,
            }),
            ..preset
        },
    );
    eprintln!(
        "frames {FIRST}..{}: joint clean {:.4} cm, ICP clean {:.4} cm ({} held), joint noisy {:.3} cm; \
         tracked but off: {:?} / {:?} / {:?}",
        FIRST + COUNT,
        clean.ate_cm,
        icp.ate_cm,
        icp.held,
        noisy.ate_cm,
        clean.dishonest,
        icp.dishonest,
        noisy.dishonest
    );
    // Measured 0.0166 cm joint, 1.09 cm ICP (21 held), 0.317 cm with noise
    // (1.48 cm with a constant bilateral range sigma; frames 316-317 off
    // by 2.2-2.4 cm on this fresh map, none in the whole sequence's run).
    assert!(clean.ate_cm <= 0.05, "clean ATE {:.4} cm", clean.ate_cm);
    assert!(clean.dishonest.is_empty(), "{:?}", clean.dishonest);
    assert!(
        icp.ate_cm > 10.0 * clean.ate_cm,
        "ICP alone {:.4} cm is not worse than joint {:.4} cm: the test no longer shows the colour term",
        icp.ate_cm,
        clean.ate_cm
    );
    assert!(noisy.ate_cm <= 0.6, "noisy ATE {:.3} cm", noisy.ate_cm);
}

#[test]
fn far_views_with_kinect_noise_are_tracked_honestly_when_the_filter_follows_the_noise() {
    let Some(dir) = common::shared_dataset("icl_office_kt0_long") else {
        return;
    };
    let sequence = Sequence::open(&dir).expect("sequence opens");
    let noisy = SlamConfig {
        simulate_noise: Some(NoiseSimulation {
            sensor: SimulatedSensor::KinectV1,
            seed: 1,
        }),
        ..SlamConfig::from_preset(sequence.preset)
    };
    let mut constant = noisy.clone();
    constant.preprocess.range_noise_factor = 0.0;
    let following = run_frames(&sequence, &dir, noisy, FAR);
    let constant = run_frames(&sequence, &dir, constant, FAR);
    eprintln!(
        "frames {FAR:?} with noise: range sigma following the noise {:.3} cm, constant {:.3} cm; \
         tracked but off: {:?} / {:?}",
        following.ate_cm, constant.ate_cm, following.dishonest, constant.dishonest
    );
    assert!(following.dishonest.is_empty(), "{:?}", following.dishonest);
    assert!(
        !constant.dishonest.is_empty(),
        "a constant range sigma tracks these frames honestly too: the test no longer shows the filter"
    );
    assert!(following.ate_cm <= 0.5, "ATE {:.3} cm", following.ate_cm);
}
