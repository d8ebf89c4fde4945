//! `surfel-slam run --save FILE` and `--load FILE` (issue #36): a run of
//! the bundled teddy clip stopped after 30 frames, saved, and continued
//! from the file with `--first 30` writes the same trajectory file, byte
//! for byte, as the run that never stopped; bad session files and a camera
//! other than the session's are refused with exit code 1 and a message
//! naming the file and the problem; a `--save` path that cannot be written
//! is refused before the run. `--load FILE --localise` places the next
//! frames in the saved map (near the ground truth, the file untouched);
//! tracking options the session's settings override are named on stderr.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::scratch;

const CLIP: &str = "www/sample/tum_fr3_teddy_clip";
/// Frames played before the session is saved.
const FIRST_PART: usize = 30;

struct Answer {
    code: i32,
    stdout: String,
    stderr: String,
}

fn run(extra: &[&std::ffi::OsStr]) -> Answer {
    let clip = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(CLIP);
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(["run".as_ref(), clip.as_os_str(), "--quiet".as_ref()])
        .args(extra)
        .output()
        .expect("the CLI runs");
    Answer {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

fn expect(case: &str, a: &Answer, code: i32, needles: &[&str]) {
    assert_eq!(a.code, code, "{case}: exit code; stderr: {}", a.stderr);
    for n in needles {
        assert!(
            a.stderr.contains(n),
            "{case}: {n:?} not in stderr: {}",
            a.stderr
        );
    }
}

fn path_arg(p: &Path) -> &std::ffi::OsStr {
    p.as_os_str()
}

#[test]
fn a_saved_run_continued_from_its_file_writes_the_same_trajectory() {
    let dir = scratch("cli-session");
    let (full, part, cont, session) = (
        dir.0.join("full.txt"),
        dir.0.join("part.txt"),
        dir.0.join("continued.txt"),
        dir.0.join("kitchen session.slam"),
    );
    let a = run(&[os("--trajectory"), path_arg(&full)]);
    expect("whole clip", &a, 0, &[]);
    let count = FIRST_PART.to_string();
    let a = run(&[
        os("--count"),
        os(&count),
        os("--trajectory"),
        path_arg(&part),
        os("--save"),
        path_arg(&session),
    ]);
    expect("first part, saved", &a, 0, &[]);
    assert!(session.is_file());
    assert!(!dir.0.join("kitchen session.slam.partial").exists());
    let a = run(&[
        os("--first"),
        os(&count),
        os("--load"),
        path_arg(&session),
        os("--trajectory"),
        path_arg(&cont),
    ]);
    expect("continued", &a, 0, &[]);
    let (full, cont) = (
        std::fs::read_to_string(&full).unwrap(),
        std::fs::read_to_string(&cont).unwrap(),
    );
    assert!(full.lines().count() > FIRST_PART + 10, "{full}");
    assert_eq!(
        cont, full,
        "the continued run's trajectory is the whole run's"
    );
    let part = std::fs::read_to_string(&part).unwrap();
    assert!(
        full.starts_with(&part),
        "the first part is the start of the whole run"
    );

    // Bad files, the wrong camera: exit 1 naming the file and the problem.
    let bytes = std::fs::read(&session).unwrap();
    let cut = dir.0.join("cut.slam");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let a = run(&[os("--first"), os(&count), os("--load"), path_arg(&cut)]);
    expect("cut", &a, 1, &["cut.slam", "truncated"]);
    let mut damaged = bytes.clone();
    let middle = damaged.len() / 3;
    damaged[middle] ^= 0xff;
    let bad = dir.0.join("damaged.slam");
    std::fs::write(&bad, &damaged).unwrap();
    let a = run(&[os("--load"), path_arg(&bad)]);
    expect("damaged", &a, 1, &["damaged.slam", "corrupt"]);
    let a = run(&[os("--load"), path_arg(&session), os("--fx"), os("600")]);
    expect("other camera", &a, 1, &["another camera", "fx"]);
    let a = run(&[os("--load"), path_arg(&dir.0.join("missing.slam"))]);
    expect("missing", &a, 1, &["missing.slam"]);
    let png = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(CLIP)
        .join("rgb")
        .read_dir()
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let a = run(&[os("--load"), path_arg(&png)]);
    expect("a PNG", &a, 1, &["not a surfel-slam session"]);

    // A --save path that cannot be written is refused before the run.
    let nowhere = dir.0.join("no such folder").join("s.slam");
    let a = run(&[os("--save"), path_arg(&nowhere)]);
    expect(
        "save into a missing folder",
        &a,
        1,
        &["--save", "folder does not exist"],
    );
    let a = run(&[os("--save"), path_arg(&dir.0)]);
    expect("save onto a folder", &a, 1, &["is a folder"]);
    let a = run(&[os("--save")]);
    expect("--save without a file", &a, 2, &["--save"]);
}

/// The number before `unit` after `label` in `text` (the summary line).
fn number_after(text: &str, label: &str, unit: &str) -> Option<f64> {
    let rest = &text[text.find(label)? + label.len()..];
    rest[..rest.find(unit)?].trim().parse().ok()
}

#[test]
fn localise_places_the_next_frames_in_the_saved_map_and_leaves_it() {
    let dir = scratch("cli-localise");
    let (session, placed) = (dir.0.join("clip.slam"), dir.0.join("placed.txt"));
    let count = FIRST_PART.to_string();
    let a = run(&[os("--count"), os(&count), os("--save"), path_arg(&session)]);
    expect("first part, saved", &a, 0, &[]);
    let saved = std::fs::read(&session).unwrap();
    let a = run(&[
        os("--first"),
        os(&count),
        os("--load"),
        path_arg(&session),
        os("--localise"),
        os("--trajectory"),
        path_arg(&placed),
    ]);
    expect("localised", &a, 0, &[]);
    let placed_count: usize = a
        .stdout
        .split(" placed (")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no placed count in {}", a.stdout));
    let text = std::fs::read_to_string(&placed).unwrap();
    let lines = text.lines().filter(|l| !l.starts_with('#')).count();
    assert_eq!(lines, placed_count, "{}", a.stdout);
    assert!(lines >= 10, "only {lines} frames placed: {}", a.stdout);
    // Against the ground truth, aligned on the saved map's frames only.
    let ate_cm = number_after(&a.stdout, "ATE in the map's frame", "cm")
        .unwrap_or_else(|| panic!("no ATE in {}", a.stdout));
    assert!(
        ate_cm < 3.0,
        "placed {ate_cm} cm from the truth: {}",
        a.stdout
    );
    assert!(a.stdout.contains("map unchanged"), "{}", a.stdout);
    assert_eq!(
        std::fs::read(&session).unwrap(),
        saved,
        "the session file changed"
    );

    // Tracking options the session's settings override are named.
    let a = run(&[
        os("--first"),
        os(&count),
        os("--count"),
        os("2"),
        os("--load"),
        path_arg(&session),
        os("--tracker"),
        os("joint"),
        os("--max-surfels"),
        os("1000"),
        os("--icp-weight"),
        os("3"),
    ]);
    expect(
        "overridden options",
        &a,
        0,
        &[
            "--tracker joint (the session's: icp)",
            "--max-surfels 1000",
            "not used",
        ],
    );
    // The session's own value is no override.
    assert!(!a.stderr.contains("--icp-weight"), "{}", a.stderr);
    let a = run(&[os("--count"), os("2"), os("--load"), path_arg(&session)]);
    assert!(!a.stderr.contains("not used"), "{}", a.stderr);

    // --localise needs --load, and saves nothing.
    let a = run(&[os("--localise")]);
    expect("--localise without --load", &a, 2, &["--load"]);
    let other = dir.0.join("other.slam");
    let a = run(&[
        os("--load"),
        path_arg(&session),
        os("--localise"),
        os("--save"),
        path_arg(&other),
    ]);
    expect("--localise with --save", &a, 2, &["--save"]);
}
