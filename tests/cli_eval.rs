//! `surfel-slam eval` end to end: association by timestamp, frame id or row
//! order, the per-pose CSV checked against the ground truth it was built
//! from, the SVG and PNG plots; and `run --fy -480` (negative numbers as
//! values) reproducing the ICL-NUIM preset's trajectory.
//!
//! Trajectories are built from the bundled sample clip's real ground truth
//! (always present) with known errors; the ICL-NUIM test reads
//! ../shared/data (skipped when absent, a failure when `CI=true`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use glam::{DAffine3, DQuat, DVec3};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{scratch, shared_dataset};
use surfel_slam::dataset::trajectory::{format_tum, parse_tum};

const CLIP_GT: &str = "www/sample/tum_fr3_teddy_clip/groundtruth.txt";

struct Answer {
    code: i32,
    stdout: String,
    stderr: String,
}

fn cli<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Answer {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(args)
        .output()
        .expect("the CLI runs");
    Answer {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn eval(est: &Path, gt: &Path, extra: &[&str]) -> Answer {
    let mut args: Vec<&std::ffi::OsStr> = vec!["eval".as_ref(), est.as_os_str(), gt.as_os_str()];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    let a = cli(&args);
    eprintln!("eval {extra:?}: exit {}\n{}{}", a.code, a.stdout, a.stderr);
    a
}

/// The real camera poses of the bundled clip's ground truth (100 Hz).
fn clip_poses() -> Vec<DAffine3> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(CLIP_GT);
    let text = std::fs::read_to_string(path).expect("bundled ground truth");
    parse_tum(&text, CLIP_GT)
        .expect("parses")
        .into_iter()
        .map(|(_, p)| p)
        .collect()
}

/// A rigid change of world: the estimate's world is not the ground truth's.
fn other_world() -> DAffine3 {
    DAffine3::from_rotation_translation(
        DQuat::from_euler(glam::EulerRot::ZYX, 0.8, -0.3, 1.9),
        DVec3::new(1.5, -0.4, 2.0),
    )
}

/// Rows of a CSV written by `eval --csv`, as numbers; checks the header.
fn read_csv(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).expect("CSV written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "timestamp,ground_truth_timestamp,position_error_m,rotation_error_deg,\
             estimate_x,estimate_y,estimate_z,ground_truth_x,ground_truth_y,ground_truth_z"
        )
    );
    lines
        .map(|l| {
            let row: Vec<f64> = l.split(',').map(|v| v.parse().expect("number")).collect();
            assert_eq!(row.len(), 10, "{l}");
            row
        })
        .collect()
}

/// The number printed after `label` in `text` (e.g. "rmse" in "ATE rmse 2.000 cm").
fn number_after(text: &str, label: &str) -> f64 {
    let start = text
        .find(label)
        .unwrap_or_else(|| panic!("{label:?} in {text}"))
        + label.len();
    text[start..]
        .split_whitespace()
        .next()
        .and_then(|v| v.trim_end_matches(',').parse().ok())
        .unwrap_or_else(|| panic!("number after {label:?} in {text}"))
}

const D: f64 = 0.02;
const SHIFT: f64 = 0.005;

/// Ground truth and estimate with a known error: each real pose appears
/// twice in the ground truth, and the estimate puts it D above then D below
/// (along the ground truth's z) in another world, stamped SHIFT seconds
/// later. The shifts cancel in the alignment, so each pose's error is
/// exactly D. Three extra estimate poses lie outside the ground truth's
/// time range. Returns (estimate, ground truth, the truth per matched pose).
fn known_error_files(dir: &Path) -> (PathBuf, PathBuf, Vec<(f64, DAffine3)>) {
    let world = other_world();
    let (mut est, mut gt) = (Vec::new(), Vec::new());
    for (k, pose) in clip_poses().iter().step_by(4).enumerate() {
        for (j, sign) in [1.0, -1.0].into_iter().enumerate() {
            let t = 100.0 + 0.2 * k as f64 + 0.1 * j as f64;
            gt.push((t, *pose));
            let mut off = *pose;
            off.translation.z += sign * D;
            est.push((t + SHIFT, world * off));
        }
    }
    let truth = gt.clone();
    for t in [50.0, 51.0, 52.0] {
        est.push((t, world));
    }
    let (e, g) = (dir.join("est.txt"), dir.join("gt.txt"));
    std::fs::write(&e, format_tum(&est)).expect("write");
    std::fs::write(&g, format_tum(&gt)).expect("write");
    (e, g, truth)
}

#[test]
fn csv_rows_are_the_matched_poses_with_their_errors() {
    let tmp = scratch("csv");
    let (est, gt, truth) = known_error_files(&tmp.0);
    let csv = tmp.0.join("errors.csv");
    let a = eval(&est, &gt, &["--csv", csv.to_str().expect("utf-8")]);
    assert_eq!(a.code, 0, "{}", a.stderr);
    let n = truth.len();
    assert!(
        a.stdout.contains(&format!(
            "({n} of {} estimate poses matched by timestamp, |dt| <= 0.02)",
            n + 3
        )),
        "{}",
        a.stdout
    );
    assert!(a
        .stdout
        .contains("ATE rmse 2.000 cm, mean 2.000 cm, median 2.000 cm, max 2.000 cm"));
    let rows = read_csv(&csv);
    assert_eq!(rows.len(), n, "one row per matched pose");
    for (row, (t, pose)) in rows.iter().zip(&truth) {
        assert!((row[0] - (t + SHIFT)).abs() < 1e-6, "{row:?}");
        assert!((row[1] - t).abs() < 1e-6, "{row:?}");
        assert!((row[2] - D).abs() < 1e-6, "position error {row:?}");
        assert!(row[3].abs() < 1e-3, "rotation error (deg) {row:?}");
        // The estimate, mapped back into the ground truth's world, sits D
        // from the true position along z.
        let g = pose.translation;
        let e = DVec3::new(row[4], row[5], row[6]);
        assert!(
            (DVec3::new(row[7], row[8], row[9]) - g).length() < 1e-6,
            "{row:?}"
        );
        assert!(
            ((e - g).abs() - DVec3::new(0.0, 0.0, D)).length() < 1e-6,
            "{row:?}"
        );
    }
    // Time association is strict about --max-dt.
    let a = eval(&est, &gt, &["--max-dt", "0.001"]);
    assert_eq!(a.code, 1);
    assert!(
        a.stderr.contains("only 0 estimate pose(s) matched"),
        "{}",
        a.stderr
    );
}

#[test]
fn frame_ids_and_row_order_pair_differently() {
    let tmp = scratch("ids");
    let poses: Vec<DAffine3> = clip_poses().into_iter().step_by(3).collect();
    let world = other_world();
    // ICL-NUIM style: the ground truth starts at frame 2, the estimate at 1.
    let gt: Vec<_> = (2..=40).map(|i| (i as f64, poses[i])).collect();
    let est: Vec<_> = (1..=40).map(|i| (i as f64, world * poses[i])).collect();
    let (e, g) = (tmp.0.join("est.txt"), tmp.0.join("gt.txt"));
    std::fs::write(&e, format_tum(&est)).expect("write");
    std::fs::write(&g, format_tum(&gt)).expect("write");
    let csv = tmp.0.join("errors.csv");
    let csv_arg = csv.to_str().expect("utf-8");

    let by_id = eval(&e, &g, &["--associate", "id", "--csv", csv_arg]);
    assert_eq!(by_id.code, 0, "{}", by_id.stderr);
    assert!(by_id
        .stdout
        .contains("39 of 40 estimate poses matched by frame id"));
    let rows = read_csv(&csv);
    assert_eq!(rows.len(), 39);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!((row[0], row[1]), ((k + 2) as f64, (k + 2) as f64));
        assert!(row[2] < 1e-6, "{row:?}");
    }
    // Whole-number stamps: time association finds the same pairs.
    let by_time = eval(&e, &g, &[]);
    assert_eq!(
        by_time.stdout.split(" (").next(),
        by_id.stdout.split(" (").next()
    );

    let by_row = eval(&e, &g, &["--associate", "order", "--csv", csv_arg]);
    assert_eq!(by_row.code, 0, "{}", by_row.stderr);
    assert!(by_row
        .stdout
        .contains("39 of 40 estimate poses matched by row order"));
    let rows = read_csv(&csv);
    assert_eq!(rows.len(), 39);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!((row[0], row[1]), ((k + 1) as f64, (k + 2) as f64));
    }
    // Frame k against frame k+1 of a moving camera: a real error.
    assert!(
        number_after(&by_row.stdout, "ATE rmse") > 0.1,
        "{}",
        by_row.stdout
    );

    // TUM timestamps are not frame ids.
    let (tum_est, tum_gt, _) = known_error_files(&tmp.0);
    let a = eval(&tum_est, &tum_gt, &["--associate", "id"]);
    assert_eq!(a.code, 1);
    assert!(
        a.stderr.contains("not a whole frame number"),
        "{}",
        a.stderr
    );
}

#[test]
fn plots_are_drawn_as_svg_and_png() {
    let tmp = scratch("plot");
    let (est, gt, truth) = known_error_files(&tmp.0);
    let svg = tmp.0.join("plot.svg");
    let a = eval(&est, &gt, &["--plot", svg.to_str().expect("utf-8")]);
    assert_eq!(a.code, 0, "{}", a.stderr);
    let text = std::fs::read_to_string(&svg).expect("SVG written");
    assert!(text.starts_with("<svg") && text.contains("ATE rmse 2.000 cm"));
    // Both trajectories and the error curve: polylines through every pose.
    let long_lines = text
        .split("<polyline")
        .skip(1)
        .filter(|l| {
            let points = l.split("points=\"").nth(1).unwrap_or("");
            let points = points.split('"').next().unwrap_or("");
            points.split_whitespace().count() >= truth.len()
        })
        .count();
    assert!(long_lines >= 3, "{long_lines} polylines through every pose");

    let png = tmp.0.join("plot.PNG");
    let a = eval(&est, &gt, &["--plot", png.to_str().expect("utf-8")]);
    assert_eq!(a.code, 0, "{}", a.stderr);
    let image = image::open(&png).expect("PNG decodes").to_rgb8();
    assert_eq!(image.dimensions(), (1200, 600));
    let count = |c: [u8; 3]| image.pixels().filter(|p| p.0 == c).count();
    // Estimate (red), error curve (blue) and text (black) are drawn.
    assert!(count([220, 40, 30]) > 300, "red {}", count([220, 40, 30]));
    assert!(count([30, 90, 200]) > 300, "blue {}", count([30, 90, 200]));
    assert!(count([0, 0, 0]) > 1000, "black {}", count([0, 0, 0]));

    // An unwritable plot path is an error naming it.
    let bad = tmp.0.join("no_such_dir").join("plot.svg");
    let a = eval(&est, &gt, &["--plot", bad.to_str().expect("utf-8")]);
    assert_eq!(a.code, 1);
    assert!(a.stderr.contains("no_such_dir"), "{}", a.stderr);
}

#[test]
fn negative_fy_on_the_command_line_matches_the_icl_preset() {
    let Some(dir) = shared_dataset("icl_office_kt0") else {
        return;
    };
    let tmp = scratch("icl");
    let run = |name: &str, extra: &[&str]| {
        let path = tmp.0.join(name);
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "run".as_ref(),
            dir.as_os_str(),
            "--quiet".as_ref(),
            "--count".as_ref(),
            "12".as_ref(),
            "--trajectory".as_ref(),
            path.as_os_str(),
        ];
        args.extend(extra.iter().map(std::ffi::OsStr::new));
        let a = cli(&args);
        eprintln!("{}{}", a.stdout, a.stderr);
        assert_eq!(a.code, 0, "{}", a.stderr);
        (path, a.stdout)
    };
    let (preset, preset_out) = run("preset.txt", &[]);
    // Another preset, every camera setting (and the noise model) given by hand, fy negative.
    let (explicit, explicit_out) = run(
        "explicit.txt",
        &[
            "--preset",
            "tum-fr1",
            "--fx",
            "481.2",
            "--fy",
            "-480",
            "--cx",
            "319.5",
            "--cy",
            "239.5",
            "--depth-max",
            "8",
            // The ICL-NUIM preset's model for its clean renderings, and its tracker.
            "--noise",
            "rendered",
            "--tracker",
            "joint",
        ],
    );
    let text = |p: &Path| std::fs::read_to_string(p).expect("trajectory");
    assert_eq!(text(&explicit), text(&preset), "same trajectory");
    let ate = |out: &str| {
        out.split("ATE ")
            .nth(1)
            .map(|s| s.split(" (").next().map(str::to_owned))
    };
    assert_eq!(ate(&explicit_out), ate(&preset_out));
    // And it is right: against the dataset's ground truth, frame ids.
    let gt = dir.join("traj0.gt.freiburg");
    let a = eval(&explicit, &gt, &["--associate", "id"]);
    assert_eq!(a.code, 0, "{}", a.stderr);
    assert!(
        a.stdout.contains("11 of 12 estimate poses matched"),
        "{}",
        a.stdout
    );
    let rmse_cm = number_after(&a.stdout, "ATE rmse");
    assert!(rmse_cm < 0.1, "ATE {rmse_cm} cm");
    // With fy = +480 the image is read upside down: the trajectory differs.
    let (flipped, _) = run("flipped.txt", &["--fy", "480"]);
    assert_ne!(text(&flipped), text(&preset));
}

/// Issue #84, part 4: `run --reference FILE` scores the run against a
/// trajectory the user brings as against ground truth. The bundled clip's
/// real ground truth is written as TUM text, as a timestamp CSV (columns
/// in another order, an extra one, and a cut-off last row: a warning) and
/// as a frame-number CSV (each frame's nearest truth pose, as ATE pairs
/// them): each gives exactly the run's ATE, named as the user's reference.
#[test]
fn run_reference_is_scored_like_the_ground_truth_in_each_format() {
    let clip = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("www/sample/tum_fr3_teddy_clip");
    let tmp = scratch("reference");
    let truth = parse_tum(
        &std::fs::read_to_string(clip.join("groundtruth.txt")).expect("truth"),
        "groundtruth.txt",
    )
    .expect("parses");
    let sequence = surfel_slam::dataset::Sequence::open(&clip).expect("the clip opens");
    let row = |key: String, p: &DAffine3| {
        let t = p.translation;
        let [qx, qy, qz, qw] = surfel_slam::se3::unit_quaternion(p);
        (
            key,
            [t.x, t.y, t.z, qx, qy, qz, qw].map(|v| format!("{v:.9}")),
        )
    };

    let tum = tmp.0.join("reference.txt");
    std::fs::write(&tum, format_tum(&truth)).expect("write");
    // qw first, then x..qz, and a column that is not read.
    let mut by_time = String::from("qw, timestamp, x, y, z, qx, qy, qz, source\n");
    for (t, p) in &truth {
        let (key, [x, y, z, qx, qy, qz, qw]) = row(format!("{t:.6}"), p);
        by_time.push_str(&format!(
            "{qw}, {key}, {x}, {y}, {z}, {qx}, {qy}, {qz}, mocap\n"
        ));
    }
    by_time.push_str("0.99, 1341841999.1, 0.1"); // the recorder stopped here
    let time_csv = tmp.0.join("reference_by_time.csv");
    std::fs::write(&time_csv, by_time).expect("write");
    let mut by_frame = String::from("frame, x, y, z, qx, qy, qz, qw\n");
    for f in &sequence.frames {
        if let Some(p) = sequence.ground_truth_for(f.timestamp, 0.02) {
            let (key, v) = row(f.index.to_string(), &p);
            by_frame.push_str(&format!("{key}, {}\n", v.join(", ")));
        }
    }
    let frame_csv = tmp.0.join("reference_by_frame.csv");
    std::fs::write(&frame_csv, by_frame).expect("write");

    for (file, by) in [
        (&tum, "timestamp"),
        (&time_csv, "timestamp"),
        (&frame_csv, "frame"),
    ] {
        let a = cli(&[
            "run".as_ref(),
            clip.as_os_str(),
            "--quiet".as_ref(),
            "--count=16".as_ref(),
            "--reference".as_ref(),
            file.as_os_str(),
        ]);
        eprintln!("{}{}", a.stdout, a.stderr);
        assert_eq!(a.code, 0, "{}", a.stderr);
        let ate = number_after(&a.stdout, "ATE ");
        let label = format!("difference from your reference ({}) ", file.display());
        let difference = number_after(&a.stdout, &label);
        assert_eq!(ate, difference, "{}", a.stdout);
        let pairs = a
            .stdout
            .split(" cm (")
            .nth(1)
            .and_then(|s| s.split(' ').next());
        // The figure as printed (an f64 would drop a trailing zero).
        let printed = a.stdout[a.stdout.find(&label).map_or(0, |i| i + label.len())..]
            .split_whitespace()
            .next()
            .unwrap_or("?");
        assert!(
            a.stdout.contains(&format!(
                "{printed} cm RMS ({} poses, by {by})",
                pairs.unwrap_or("?")
            )),
            "{}",
            a.stdout
        );
        let cut_off = a.stderr.matches("the last line is cut off").count();
        assert_eq!(cut_off, usize::from(file == &time_csv), "{}", a.stderr);
    }

    // A reference that cannot be read stops before the run, naming the line.
    let bad = tmp.0.join("bad.csv");
    std::fs::write(&bad, "frame, x, y, z, qx, qy, qw\n0, 0, 0, 0, 0, 0, 1\n").expect("write");
    let out = tmp.0.join("never.txt");
    let a = cli(&[
        "run".as_ref(),
        clip.as_os_str(),
        "--quiet".as_ref(),
        "--reference".as_ref(),
        bad.as_os_str(),
        "--trajectory".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(a.code, 1, "{}", a.stderr);
    assert!(
        a.stderr.contains("bad.csv, line 1") && a.stderr.contains("no `qz` column"),
        "{}",
        a.stderr
    );
    assert!(!out.exists());
}
