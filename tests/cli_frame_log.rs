//! `surfel-slam run --frame-log` and `--simulate-noise`: one CSV row per
//! input frame (an unreadable one too), each frame's error against the
//! truth's motion, and the noise a clean sequence is given, on the first
//! frames of the shared ICL-NUIM kt0.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use std::path::Path;
use std::process::Command;

/// The first `n` frames of ICL-NUIM kt0 copied to `to`, with frame
/// `broken`'s depth PNG cut short.
fn copy_icl(from: &Path, to: &Path, n: usize, broken: usize) {
    for sub in ["depth", "rgb"] {
        std::fs::create_dir_all(to.join(sub)).unwrap();
    }
    let mut index = String::new();
    for i in 1..=n {
        index.push_str(&format!("{i} depth/{i}.png {i} rgb/{i}.png\n"));
        for sub in ["depth", "rgb"] {
            let name = format!("{sub}/{i}.png");
            let bytes = std::fs::read(from.join(&name)).unwrap();
            let keep = if sub == "depth" && i == broken + 1 {
                bytes.len() / 3
            } else {
                bytes.len()
            };
            std::fs::write(to.join(&name), &bytes[..keep]).unwrap();
        }
    }
    std::fs::write(to.join("associations.txt"), index).unwrap();
    std::fs::copy(from.join("traj0.gt.freiburg"), to.join("traj0.gt.freiburg")).unwrap();
}

/// The rows of a frame log, as column name -> value maps.
fn rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).expect("frame log written");
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(str::to_owned)
        .collect();
    for name in ["frame", "timestamp", "verdict", "rpe_cm", "rpe_deg"] {
        assert!(header.iter().any(|h| h == name), "{name} in {header:?}");
    }
    lines
        .map(|line| {
            let values: Vec<&str> = line.split(',').collect();
            assert_eq!(values.len(), header.len(), "{line}");
            header
                .iter()
                .cloned()
                .zip(values.into_iter().map(str::to_owned))
                .collect()
        })
        .collect()
}

/// Runs the CLI on `dataset` with a frame log; its stdout and stderr.
fn run(dataset: &Path, log: &Path, extra: &[&str]) -> (String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run", "-q", "--frame-log"])
        .arg(log)
        .args(extra)
        .arg(dataset)
        .output()
        .expect("runs");
    // Exit 3: some frames were skipped as unreadable.
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_frame_log_has_a_row_per_input_frame_and_judges_each_against_the_truth() {
    let Some(icl) = common::shared_dataset("icl_office_kt0") else {
        return;
    };
    let scratch = common::scratch("frame-log");
    let dataset = scratch.0.join("icl");
    copy_icl(&icl, &dataset, 24, 7);
    let clean_log = scratch.0.join("clean.csv");
    run(&dataset, &clean_log, &[]);
    let clean = rows(&clean_log);
    assert_eq!(clean.len(), 24);
    for (i, row) in clean.iter().enumerate() {
        assert_eq!(row["frame"], i.to_string());
        assert_eq!(row["timestamp"], (i + 1).to_string());
        let verdict = row["verdict"].as_str();
        match i {
            0 => assert_eq!(verdict, "initialised"),
            7 => {
                assert_eq!(verdict, "unreadable");
                assert!(row["rpe_cm"].is_empty() && row["tx"].is_empty());
            }
            // Clean rendered depth: every frame tracked, each motion within
            // a millimetre and a tenth of a degree of the truth's (after
            // the unreadable frame, the motion over two frames). The
            // truth has no pose for the first frame, so the second frame's
            // motion cannot be judged.
            1 => {
                assert_eq!(verdict, "tracked");
                assert!(row["rpe_cm"].is_empty() && !row["tx"].is_empty());
            }
            _ => {
                assert_eq!(verdict, "tracked", "frame {i}");
                let cm: f64 = row["rpe_cm"].parse().expect("rpe_cm");
                let deg: f64 = row["rpe_deg"].parse().expect("rpe_deg");
                assert!(cm < 0.1 && deg < 0.1, "frame {i}: {cm} cm, {deg} deg");
            }
        }
    }

    // The same frames with Kinect v1 noise simulated: a different
    // trajectory, the same one for the same seed, another for another seed.
    let noisy = |seed: &str| {
        let log = scratch.0.join(format!("noisy-{seed}.csv"));
        run(
            &dataset,
            &log,
            &["--simulate-noise", "kinect-v1", "--noise-seed", seed],
        );
        rows(&log)
    };
    let pose = |rows: &[std::collections::HashMap<String, String>]| -> Vec<String> {
        rows.iter()
            .map(|r| format!("{} {} {}", r["tx"], r["ty"], r["tz"]))
            .collect()
    };
    let (a, b, c) = (noisy("1"), noisy("1"), noisy("2"));
    assert_eq!(pose(&a), pose(&b));
    assert_ne!(pose(&a), pose(&c));
    assert_ne!(pose(&a), pose(&clean));
    // Kinect-v1 noise on a 2-3 m office: each frame's motion is still
    // right to a centimetre.
    for row in a
        .iter()
        .filter(|r| r["verdict"] == "tracked" && !r["rpe_cm"].is_empty())
    {
        let cm: f64 = row["rpe_cm"].parse().expect("rpe_cm");
        assert!(cm < 1.0, "frame {}: {cm} cm", row["frame"]);
    }
}

#[test]
fn depth_only_leaves_the_colour_unread_and_tracks_on_geometry() {
    let Some(icl) = common::shared_dataset("icl_office_kt0") else {
        return;
    };
    let scratch = common::scratch("frame-log-depth-only");
    let dataset = scratch.0.join("icl");
    copy_icl(&icl, &dataset, 16, 5);
    let (colour_log, depth_log) = (scratch.0.join("colour.csv"), scratch.0.join("depth.csv"));
    let (_, colour_err) = run(&dataset, &colour_log, &[]);
    let (_, depth_err) = run(&dataset, &depth_log, &["--depth-only"]);
    assert_eq!(
        colour_err.matches("no colour images").count(),
        0,
        "{colour_err}"
    );
    assert_eq!(
        depth_err.matches("no colour images").count(),
        1,
        "{depth_err}"
    );
    assert!(
        depth_err.contains("icp, not --tracker joint"),
        "{depth_err}"
    );
    let (colour, depth) = (rows(&colour_log), rows(&depth_log));
    assert_eq!(depth.len(), 16);
    // ICL-NUIM's joint tracker against ICP alone: other poses, each motion
    // still right to a millimetre on clean rendered depth.
    let poses = |rows: &[std::collections::HashMap<String, String>]| -> Vec<String> {
        rows.iter()
            .map(|r| format!("{} {}", r["tx"], r["qw"]))
            .collect()
    };
    assert_ne!(poses(&colour), poses(&depth));
    for row in depth.iter().filter(|r| !r["rpe_cm"].is_empty()) {
        assert_eq!(row["verdict"], "tracked", "frame {}", row["frame"]);
        let cm: f64 = row["rpe_cm"].parse().expect("rpe_cm");
        assert!(cm < 0.1, "frame {}: {cm} cm", row["frame"]);
    }
}
