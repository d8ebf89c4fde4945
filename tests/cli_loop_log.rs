//! `surfel-slam run --loop-log`: the loop stage's record as CSV, on the
//! shared 7-Scenes kitchen (half resolution, past the active window so that
//! the global check looks).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use std::process::Command;
use surfel_slam::loop_closure::loop_log::LOOP_LOG_HEADER;

#[test]
fn the_loop_log_has_a_row_per_checked_frame() {
    let Some(dir) = common::shared_dataset("7scenes_redkitchen_even") else {
        return;
    };
    let scratch = common::scratch("loop-log");
    std::fs::create_dir_all(&scratch.0).expect("scratch");
    let log = scratch.0.join("loop.csv");
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run", "-q", "--half", "--count", "221", "--loop-log"])
        .arg(&log)
        .arg(&dir)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&log).expect("log written");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(LOOP_LOG_HEADER));
    let columns: Vec<&str> = LOOP_LOG_HEADER.split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let column = |row: &Vec<&str>, name: &str| {
        let i = columns.iter().position(|c| *c == name).expect("column");
        row[i].to_owned()
    };
    for row in &rows {
        assert_eq!(row.len(), columns.len(), "{row:?}");
    }
    // The global check looks at frames 200, 210 and 220 (every 10th, once
    // keyframes 200 frames old can exist); nothing before the window ends.
    let frames: Vec<u32> = rows
        .iter()
        .map(|r| column(r, "frame").parse().expect("frame number"))
        .collect();
    for looked in [200, 210, 220] {
        let row = &rows[frames
            .iter()
            .position(|&f| f == looked)
            .expect("a row for a look")];
        assert!(
            !column(row, "global_refused").is_empty() || column(row, "decision") == "closed-global",
            "frame {looked}: a look says what it found: {row:?}"
        );
        assert!(!column(row, "global_candidates").is_empty());
    }
    assert!(frames.iter().all(|&f| f >= 200), "{frames:?}");
    assert!(frames.windows(2).all(|w| w[0] < w[1]), "{frames:?}");
}
