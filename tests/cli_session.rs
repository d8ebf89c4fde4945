//! `surfel-slam run --save FILE` and `--load FILE` (issue #36): a run of
//! the bundled teddy clip stopped after 30 frames, saved, and continued
//! from the file with `--first 30` writes the same trajectory file, byte
//! for byte, as the run that never stopped; bad session files and a camera
//! other than the session's are refused with exit code 1 and a message
//! naming the file and the problem; a `--save` path that cannot be written
//! is refused before the run.
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
