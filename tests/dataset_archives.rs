//! Datasets as archives and half-copied datasets, through the command line.
//!
//! - teddy packed as `.tgz`, `.zip` and `.tar` (built here from
//!   ../shared/data/tum_fr3_teddy) runs every 5th frame to the same ATE as
//!   the folder;
//!   corrupt and truncated archives are refused with a message naming them.
//! - A half-copied teddy (every 7th colour PNG deleted, one more replaced by a
//!   dangling link) runs: each such frame is skipped with a message naming its
//!   file, the ATE against ground truth stays close to the full run's.
//! - The bundled clip (always present) as an archive, for machines without
//!   ../shared.
//!
//! `--nocapture` prints the measured numbers.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;
use common::scratch;

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use surfel_slam::dataset::{list_files, DatasetSource, Sequence};

/// Packs `dir` as `<out>` under the top folder `top` (as downloads are).
fn pack(dir: &Path, top: &str, out: &Path) {
    let names = list_files(dir).expect("list");
    let file = File::create(out).expect("create archive");
    let name = out.to_string_lossy();
    if name.ends_with(".zip") {
        let mut zip = zip::ZipWriter::new(file);
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .compression_level(Some(1));
        for n in &names {
            zip.start_file(format!("{top}/{n}"), options)
                .expect("entry");
            zip.write_all(&std::fs::read(dir.join(n)).expect("read"))
                .expect("write");
        }
        zip.finish().expect("zip");
    } else {
        let sink: Box<dyn Write> = if name.ends_with(".tar") {
            Box::new(file)
        } else {
            Box::new(flate2::write::GzEncoder::new(
                file,
                flate2::Compression::fast(),
            ))
        };
        let mut tar = tar::Builder::new(sink);
        for n in &names {
            tar.append_path_with_name(dir.join(n), format!("{top}/{n}"))
                .expect("entry");
        }
        tar.into_inner().expect("tar").flush().expect("flush");
    }
}

struct Answer {
    code: i32,
    stderr: String,
    stdout: String,
}

fn run_cli(dataset: &Path) -> Answer {
    run_cli_with(dataset, &[])
}

/// `surfel-slam run <dataset> --quiet <extra>`.
fn run_cli_with(dataset: &Path, extra: &[&str]) -> Answer {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .arg("run")
        .arg(dataset)
        .arg("--quiet")
        .args(extra)
        .output()
        .expect("the CLI runs");
    Answer {
        code: out.status.code().unwrap_or(-1),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
    }
}

/// The `ATE X cm` of the summary line, in centimetres.
fn ate_cm(a: &Answer) -> f64 {
    let line = a.stdout.lines().last().unwrap_or("");
    let at = line
        .find("ATE ")
        .unwrap_or_else(|| panic!("no ATE in {line:?}; stderr:\n{}", a.stderr));
    line[at + 4..]
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no ATE number in {line:?}"))
}

/// The summary's `N frames` and `N unreadable`.
fn summary_count(a: &Answer, word: &str) -> usize {
    let line = a.stdout.lines().last().unwrap_or("");
    let words: Vec<&str> = line.split_whitespace().collect();
    words
        .windows(2)
        .find(|w| w[1].trim_end_matches(',') == word)
        .and_then(|w| w[0].trim_start_matches(':').parse().ok())
        .unwrap_or_else(|| panic!("no `{word}` count in {line:?}"))
}

#[test]
fn teddy_archives_give_the_folders_ate() {
    let Some(teddy) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let tmp = scratch("teddy");
    // Every 5th frame: frames from all through the archive, at a fifth of
    // a full run's cost.
    let stride = ["--stride", "5"];
    let folder = run_cli_with(&teddy, &stride);
    assert_eq!(folder.code, 0, "folder run: {}", folder.stderr);
    let folder_ate = ate_cm(&folder);
    eprintln!("folder: {}", folder.stdout.trim());
    let folder_sequence = Sequence::open(&teddy).expect("folder");
    for name in ["teddy.tgz", "teddy.zip", "teddy.tar"] {
        let archive = tmp.0.join(name);
        pack(&teddy, "rgbd_dataset_freiburg3_teddy", &archive);
        // The same frames (under the archive's top folder) and ground truth.
        let sequence = Sequence::open(&archive).expect("archive opens");
        assert_eq!(sequence.frames.len(), folder_sequence.frames.len());
        assert_eq!(sequence.ground_truth, folder_sequence.ground_truth);
        assert_eq!(sequence.preset, folder_sequence.preset);
        assert_eq!(
            sequence.frames[5].colour,
            folder_sequence.frames[5]
                .colour
                .as_ref()
                .map(|c| format!("rgbd_dataset_freiburg3_teddy/{c}"))
        );
        let a = run_cli_with(&archive, &stride);
        eprintln!(
            "{name} ({} MB): {}",
            std::fs::metadata(&archive).map_or(0, |m| m.len() >> 20),
            a.stdout.trim()
        );
        assert_eq!(a.code, 0, "{name}: {}", a.stderr);
        assert_eq!(
            summary_count(&a, "frames"),
            folder_sequence.frames.len().div_ceil(5),
            "{name}"
        );
        let ate = ate_cm(&a);
        // Same frames, same run (a run does not depend on timing).
        assert_eq!(
            ate, folder_ate,
            "{name}: ATE {ate} cm, folder {folder_ate} cm"
        );
    }
}

#[test]
fn corrupt_and_truncated_archives_are_refused_by_name() {
    let clip = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("www/sample/tum_fr3_teddy_clip");
    let tmp = scratch("corrupt");
    for name in ["clip.tgz", "clip.zip", "clip.tar"] {
        let archive = tmp.0.join(name);
        pack(&clip, "clip", &archive);
        // Whole: runs (the bundled clip has ground truth).
        let a = run_cli(&archive);
        assert_eq!(a.code, 0, "{name}: {}", a.stderr);
        assert!(ate_cm(&a) < 2.0, "{name}: {}", a.stdout);

        let bytes = std::fs::read(&archive).expect("read");
        let truncated = tmp.0.join(format!("truncated-{name}"));
        std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("write");
        let a = run_cli(&truncated);
        eprintln!("| truncated {name} | exit {} | {}", a.code, a.stderr.trim());
        assert_eq!(a.code, 1, "truncated {name}: {}", a.stderr);
        assert!(
            a.stderr.contains(&truncated.display().to_string()),
            "names the archive: {}",
            a.stderr
        );
        assert!(!a.stderr.contains("panicked"), "{}", a.stderr);
    }
    let garbage = tmp.0.join("garbage.zip");
    std::fs::write(&garbage, b"not an archive at all".repeat(100)).expect("write");
    let a = run_cli(&garbage);
    eprintln!("| garbage.zip | exit {} | {}", a.code, a.stderr.trim());
    assert_eq!(a.code, 1);
    assert!(
        a.stderr.contains("garbage.zip") && a.stderr.contains("not a .zip, .tar or .tar.gz"),
        "{}",
        a.stderr
    );
    // Data damaged inside a zip entry: that frame is skipped by name, the rest run.
    let zip_path = tmp.0.join("clip.zip");
    let mut bytes = std::fs::read(&zip_path).expect("read");
    let mut source = DatasetSource::open(&zip_path).expect("opens");
    let sequence = source.sequence().expect("sequence");
    let victim = sequence.frames[3].depth.clone();
    let at = bytes
        .windows(victim.len())
        .position(|w| w == victim.as_bytes())
        .expect("local header")
        + victim.len()
        + 200;
    for b in &mut bytes[at..at + 64] {
        *b ^= 0xa5;
    }
    let damaged = tmp.0.join("damaged.zip");
    std::fs::write(&damaged, &bytes).expect("write");
    let a = run_cli(&damaged);
    eprintln!(
        "| damaged entry in a zip | exit {} | {}",
        a.code,
        a.stderr.trim()
    );
    assert_eq!(a.code, 3, "{}", a.stderr);
    assert!(
        a.stderr.contains("frame 3 skipped") && a.stderr.contains(&victim),
        "{}",
        a.stderr
    );
}

#[test]
fn half_copied_teddy_skips_the_missing_frames() {
    let Some(teddy) = common::shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let tmp = scratch("half");
    let dir = tmp.0.join("tum_fr3_teddy");
    for n in list_files(&teddy).expect("list") {
        let to = dir.join(&n);
        std::fs::create_dir_all(to.parent().expect("parent")).expect("dir");
        std::fs::copy(teddy.join(&n), &to).expect("copy");
    }
    let full = Sequence::open(&teddy).expect("teddy");
    // Every 7th colour PNG of the index deleted.
    let rgb = std::fs::read_to_string(teddy.join("rgb.txt")).expect("rgb.txt");
    let colours: Vec<&str> = rgb
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    let deleted: Vec<&str> = colours.iter().copied().skip(6).step_by(7).collect();
    for c in &deleted {
        std::fs::remove_file(dir.join(c)).expect("remove");
    }
    // One more depth image present in the listing but unreadable (a dangling link).
    let dangling = full.frames[10].depth.clone();
    #[cfg(unix)]
    {
        std::fs::remove_file(dir.join(&dangling)).expect("remove");
        std::os::unix::fs::symlink(tmp.0.join("nowhere.png"), dir.join(&dangling))
            .expect("symlink");
    }
    let skipped_frames: Vec<usize> = full
        .frames
        .iter()
        .filter(|f| {
            deleted.contains(&f.colour.as_deref().unwrap_or_default())
                || (cfg!(unix) && f.depth == dangling)
        })
        .map(|f| f.index)
        .collect();

    let a = run_cli(&dir);
    let skipped: Vec<&str> = a.stderr.lines().filter(|l| l.contains("skipped")).collect();
    eprintln!("half-copied teddy: {}", a.stdout.trim());
    for line in &skipped {
        eprintln!("  {line}");
    }
    assert_eq!(a.code, 3, "finished with frames skipped: {}", a.stderr);
    assert_eq!(summary_count(&a, "frames"), full.frames.len());
    assert_eq!(summary_count(&a, "unreadable"), skipped_frames.len());
    assert_eq!(skipped.len(), skipped_frames.len(), "{}", a.stderr);
    for (line, index) in skipped.iter().zip(&skipped_frames) {
        let frame = &full.frames[*index];
        assert!(line.contains(&format!("frame {index} skipped")), "{line}");
        if deleted.contains(&frame.colour.as_deref().unwrap_or_default()) {
            assert!(
                line.contains(&format!(
                    "{} is missing (listed in rgb.txt)",
                    frame.colour.as_deref().unwrap_or_default()
                )),
                "{line}"
            );
        } else {
            assert!(line.contains(&frame.depth), "{line}");
        }
    }
    let ate = ate_cm(&a);
    eprintln!(
        "half-copied teddy: {} of {} frames ran, ATE {ate:.3} cm",
        full.frames.len() - skipped_frames.len(),
        full.frames.len()
    );
    // Against the dataset's ground truth: the full run gives 0.71 cm.
    assert!(ate < 1.5, "ATE {ate} cm");

    // Nothing readable at all: refused, by a message naming a missing file.
    for c in &colours {
        let _ = std::fs::remove_file(dir.join(c));
    }
    let a = run_cli(&dir);
    eprintln!(
        "| no colour image left | exit {} | {}",
        a.code,
        a.stderr.trim()
    );
    assert_eq!(a.code, 1, "{}", a.stderr);
    assert!(
        a.stderr.contains("none of the")
            && a.stderr.contains("frames listed can be read")
            && a.stderr.contains("is missing (listed in rgb.txt)"),
        "{}",
        a.stderr
    );
}

/// A 7-Scenes folder (`seq-01/frame-NNNNNN.{color.png,depth.png,pose.txt}`)
/// from the bundled clip's first `n` frames with ground truth: depth rescaled
/// to millimetres, poses from its ground truth. Returns the folder.
fn seven_scenes_from_clip(root: &Path, n: usize) -> PathBuf {
    let clip = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("www/sample/tum_fr3_teddy_clip");
    let tum = Sequence::open(&clip).expect("clip");
    let dir = root.join("seven_scenes_teddy");
    std::fs::create_dir_all(dir.join("seq-01")).expect("dir");
    let mut written = 0;
    for f in &tum.frames {
        let Some(pose) = tum.ground_truth_for(f.timestamp, 0.02) else {
            continue;
        };
        let stem = dir.join(format!("seq-01/frame-{written:06}"));
        std::fs::copy(
            clip.join(f.colour.as_deref().expect("colour")),
            stem.with_extension("color.png"),
        )
        .expect("copy");
        let depth = image::open(clip.join(&f.depth))
            .expect("depth")
            .into_luma16();
        let mm = image::ImageBuffer::from_fn(depth.width(), depth.height(), |x, y| {
            image::Luma([(f32::from(depth.get_pixel(x, y)[0]) / 5.0).round() as u16])
        });
        mm.save(stem.with_extension("depth.png"))
            .expect("depth png");
        let m = glam::DMat4::from(pose);
        let text: String = (0..4)
            .map(|r| {
                let row = m.row(r);
                format!("{:.12} {:.12} {:.12} {:.12}\n", row.x, row.y, row.z, row.w)
            })
            .collect();
        std::fs::write(stem.with_extension("pose.txt"), text).expect("pose");
        written += 1;
        if written == n {
            break;
        }
    }
    dir
}

#[test]
fn seven_scenes_ground_truth_from_pose_files_in_a_folder_and_a_zip() {
    let tmp = scratch("7scenes");
    let dir = seven_scenes_from_clip(&tmp.0, 12);
    let zip = tmp.0.join("seven_scenes_teddy.zip");
    pack(&dir, "seven_scenes_teddy", &zip);
    for path in [&dir, &zip] {
        let sequence = Sequence::open(path).expect("opens");
        assert_eq!(sequence.frames.len(), 12);
        assert_eq!(sequence.ground_truth.len(), 12, "{}", path.display());
        let a = run_cli(path);
        eprintln!("7-Scenes from the clip: {}", a.stdout.trim());
        assert_eq!(a.code, 0, "{}", a.stderr);
        assert!(ate_cm(&a) < 5.0, "{}", a.stdout);
    }
    // A pose file that cannot be read (a dangling link): a warning, that frame
    // without ground truth; the run goes on.
    #[cfg(unix)]
    {
        let pose = dir.join("seq-01/frame-000004.pose.txt");
        std::fs::remove_file(&pose).expect("remove");
        std::os::unix::fs::symlink(tmp.0.join("nowhere.txt"), &pose).expect("symlink");
        let sequence = Sequence::open(&dir).expect("opens");
        assert_eq!(sequence.ground_truth.len(), 11);
        assert_eq!(sequence.warnings.len(), 1);
        let a = run_cli(&dir);
        assert_eq!(a.code, 0, "{}", a.stderr);
        assert!(
            a.stderr.contains("warning: cannot read") && a.stderr.contains("frame-000004.pose.txt"),
            "{}",
            a.stderr
        );
    }
}
