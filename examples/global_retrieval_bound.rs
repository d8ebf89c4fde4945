//! Is keyframe retrieval what keeps the global loop check from closing on
//! a real sequence? The sequence is played with the global look's fern
//! limit and candidate count widened (every old keyframe may be tried, the
//! `--candidates` most similar of them), so that the checks after
//! retrieval (registration, conditioning, distance to the keyframe, free
//! space, photometric agreement, correction size, second answer) decide.
//! Per look: the keyframes tried, the last one's check and its true
//! relation to the frame (ground truth), and the pose's error before and
//! after against the truth aligned on the frames older than the active
//! window (as `tests/kitchen_loop.rs` judges decisions).
//!
//! `cargo run --release --example global_retrieval_bound -- ../shared/data/7scenes_redkitchen_even [--candidates 10] [--limit 1.0]`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::eval::{ate, errors_in_early_alignment};
use surfel_slam::se3::motion_magnitude;
use surfel_slam::{Pipeline, SlamConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut dir = None;
    let (mut candidates, mut limit) = (10usize, 1.0f32);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--candidates" => candidates = args.next().and_then(|v| v.parse().ok()).expect("N"),
            "--limit" => limit = args.next().and_then(|v| v.parse().ok()).expect("limit"),
            _ => dir = Some(std::path::PathBuf::from(a)),
        }
    }
    let dir = dir.ok_or("usage: global_retrieval_bound <dataset> [--candidates N] [--limit D]")?;
    let sequence = Sequence::open(&dir)?;
    let mut config = SlamConfig::from_preset(sequence.preset);
    config.relocalise.max_dissimilarity = limit;
    config.relocalise.candidates = candidates;
    let window = config.fusion.active_window_frames as usize;
    let mut slam = Pipeline::new(config.clone())?;
    let truth_of = |i: usize| sequence.ground_truth_for(sequence.frames[i].timestamp, 0.02);
    println!(
        "{}: fern limit {limit}, {candidates} candidates",
        dir.display()
    );
    println!("frame | tried | last tried: keyframe, dissimilarity, check | its correction | its truth: cm, deg | miss / closure | off the truth before -> after, cm");
    for (i, entry) in sequence.frames.iter().enumerate() {
        let frame = read_frame(&dir, entry, &config.depth)?;
        let report = slam.push_frame(&frame, entry.timestamp)?;
        let o = &report.loop_outcome;
        if !o.global_looked {
            continue;
        }
        let attempt = o.global_attempt.map_or("-".to_string(), |a| {
            format!(
                "{}, {:.3}, {}",
                a.keyframe_frame,
                a.dissimilarity,
                a.refused.map_or("passed", |r| r.name())
            )
        });
        // The correction the last registration asks for (passed or not).
        let correction = o.global_attempt.map_or("-".to_string(), |a| {
            let (dt, dr) = motion_magnitude(&(o.tracked.inverse() * a.world_from_camera));
            format!("{:.2} cm {:.2} deg", dt * 100.0, dr.to_degrees())
        });
        let relation = o
            .global_attempt
            .and_then(|a| Some((truth_of(a.keyframe_frame as usize)?, truth_of(i)?)))
            .map_or("-".to_string(), |(k, f)| {
                let (dt, _) = motion_magnitude(&(k.inverse() * f));
                let deg = k
                    .matrix3
                    .z_axis
                    .angle_between(f.matrix3.z_axis)
                    .to_degrees();
                format!("{:.1}, {deg:.1}", dt * 100.0)
            });
        let outcome = match (&o.global, o.global_miss) {
            (Some(g), _) => format!(
                "{} {:.2} cm {:.2} deg",
                if g.closed { "closed" } else { "not bent" },
                g.correction_m * 100.0,
                g.correction_deg
            ),
            (None, Some(m)) => m.name().to_string(),
            (None, None) => "-".to_string(),
        };
        let errors = o
            .corrected_pose()
            .filter(|_| i > window)
            .and_then(|corrected| {
                let trajectory = slam.trajectory();
                errors_in_early_alignment(
                    trajectory,
                    &sequence.ground_truth,
                    0.02,
                    (trajectory[i - window - 1].0, entry.timestamp),
                    &[o.tracked, corrected],
                )
                .ok()
                .flatten()
            })
            .map_or("-".to_string(), |e| {
                format!("{:.2} -> {:.2}", e[0] * 100.0, e[1] * 100.0)
            });
        println!(
            "{i} | {} | {attempt} | {correction} | {relation} | {outcome} | {errors}",
            o.global_candidates
        );
    }
    let rmse = ate(slam.trajectory(), &sequence.ground_truth, 0.02)?.rmse_m;
    println!(
        "ATE {:.3} cm, {} closures ({} global)",
        rmse * 100.0,
        slam.loop_closures(),
        slam.global_loop_closures()
    );
    Ok(())
}
