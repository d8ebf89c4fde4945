//! The command line on bad input: every case is refused with a message on
//! stderr naming the file (or the setting) and the problem, and a documented
//! exit code (1: nothing could run; 2: bad command line; 3: the run
//! finished, some frames were skipped). Folders are cut from the bundled
//! sample clip (always present).
//!
//! Run with `--nocapture` to print the table of answers.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::scratch;

use image::{imageops::FilterType, DynamicImage, ImageFormat};

const CLIP: &str = "www/sample/tum_fr3_teddy_clip";
const FRAMES: usize = 4;

/// A TUM folder with the clip's first `FRAMES` frames; returns (dir, colour paths, depth paths).
fn tum_clip(root: &Path, name: &str) -> (PathBuf, Vec<String>, Vec<String>) {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(CLIP);
    let dst = root.join(name);
    let mut lists = Vec::new();
    for (file, sub) in [("rgb.txt", "rgb"), ("depth.txt", "depth")] {
        std::fs::create_dir_all(dst.join(sub)).expect("dir");
        let text = std::fs::read_to_string(src.join(file)).expect("index");
        let rows: Vec<&str> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .take(FRAMES)
            .collect();
        let mut paths = Vec::new();
        for row in &rows {
            let rel = row.split_whitespace().nth(1).expect("path");
            std::fs::copy(src.join(rel), dst.join(rel)).expect("copy");
            paths.push(rel.to_owned());
        }
        std::fs::write(dst.join(file), rows.join("\n") + "\n").expect("write");
        lists.push(paths);
    }
    let gt = std::fs::read_to_string(src.join("groundtruth.txt")).expect("gt");
    std::fs::write(dst.join("groundtruth.txt"), gt).expect("gt");
    let depth = lists.pop().expect("depth");
    let colour = lists.pop().expect("colour");
    (dst, colour, depth)
}

fn png(img: &DynamicImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, ImageFormat::Png).expect("encode");
    out.into_inner()
}

fn load(path: &Path) -> DynamicImage {
    image::open(path).expect("decodable")
}

struct Answer {
    code: i32,
    stderr: String,
    stdout: String,
}

fn run(dir: &Path, extra: &[&str]) -> Answer {
    let mut args: Vec<&std::ffi::OsStr> = vec!["run".as_ref(), dir.as_os_str(), "--quiet".as_ref()];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    cli(&args)
}

fn cli<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Answer {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .args(args)
        .output()
        .expect("the CLI runs");
    Answer {
        code: out.status.code().unwrap_or(-1),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
    }
}

/// Checks the exit code and that stderr holds every needle; prints the answer.
fn expect(case: &str, a: &Answer, code: i32, needles: &[&str]) {
    let message = a
        .stderr
        .lines()
        .find(|l| l.starts_with("error") || l.contains("skipped") || l.contains("unreadable"))
        .unwrap_or("");
    eprintln!("| {case} | exit {} | {message} |", a.code);
    assert_eq!(a.code, code, "{case}: exit code; stderr:\n{}", a.stderr);
    for n in needles {
        assert!(
            a.stderr.contains(n),
            "{case}: stderr lacks {n:?}:\n{}",
            a.stderr
        );
    }
}

#[test]
fn bad_frames_are_named_and_skipped() {
    let tmp = scratch("frames");
    let (dir, colour, depth) = tum_clip(&tmp.0, "rgbd_dataset_freiburg3_bad");
    let depth1 = load(&dir.join(&depth[1]));
    let colour1 = load(&dir.join(&colour[1]));
    // The first frame is good; frame 1 gets each defect in turn.
    type Defect = (&'static str, Box<dyn Fn()>, Vec<String>);
    let base = |s: &str| s.rsplit('/').next().unwrap_or(s).to_owned();
    let (c1, d1) = (dir.join(&colour[1]), dir.join(&depth[1]));
    let cases: Vec<Defect> = vec![
        (
            "corrupt colour PNG",
            Box::new({
                let c1 = c1.clone();
                move || std::fs::write(&c1, b"this is not a PNG".repeat(20)).expect("write")
            }),
            vec![base(&colour[1]), "could not be decoded".into()],
        ),
        (
            "truncated depth PNG",
            Box::new({
                let d1 = d1.clone();
                let bytes = png(&depth1);
                move || std::fs::write(&d1, &bytes[..bytes.len() / 2]).expect("write")
            }),
            vec![base(&depth[1]), "could not be decoded".into()],
        ),
        (
            "8-bit depth PNG",
            Box::new({
                let d1 = d1.clone();
                let bytes = png(&DynamicImage::ImageLuma8(depth1.to_luma8()));
                move || std::fs::write(&d1, &bytes).expect("write")
            }),
            vec![base(&depth[1]), "16-bit".into()],
        ),
        (
            "RGB depth PNG",
            Box::new({
                let d1 = d1.clone();
                let bytes = png(&DynamicImage::ImageRgb8(depth1.to_rgb8()));
                move || std::fs::write(&d1, &bytes).expect("write")
            }),
            vec![base(&depth[1]), "16-bit".into()],
        ),
        (
            "colour/depth size mismatch",
            Box::new({
                let c1 = c1.clone();
                let bytes = png(&colour1.resize_exact(320, 240, FilterType::Nearest));
                move || std::fs::write(&c1, &bytes).expect("write")
            }),
            vec![
                base(&colour[1]),
                "colour is 320x240 but depth is 640x480".into(),
            ],
        ),
        (
            "frame size differs from the sequence's",
            Box::new({
                let (c1, d1) = (c1.clone(), d1.clone());
                let cb = png(&colour1.resize_exact(320, 240, FilterType::Nearest));
                let db = png(&depth1.resize_exact(320, 240, FilterType::Nearest));
                move || {
                    std::fs::write(&c1, &cb).expect("write");
                    std::fs::write(&d1, &db).expect("write");
                }
            }),
            vec![
                base(&depth[1]),
                "frame is 320x240 but the sequence is 640x480".into(),
            ],
        ),
    ];
    let (good_c, good_d) = (
        std::fs::read(&c1).expect("c"),
        std::fs::read(&d1).expect("d"),
    );
    for (case, damage, needles) in cases {
        std::fs::write(&c1, &good_c).expect("restore");
        std::fs::write(&d1, &good_d).expect("restore");
        damage();
        let a = run(&dir, &[]);
        let needles: Vec<&str> = needles.iter().map(String::as_str).collect();
        expect(case, &a, 3, &needles);
        // The other frames were processed: the pipeline stayed usable.
        assert!(
            a.stdout.contains(&format!("{FRAMES} frames")) && a.stdout.contains("1 unreadable"),
            "{case}: {}",
            a.stdout
        );
        assert!(a.stdout.contains(" 0 lost"), "{case}: {}", a.stdout);
    }
}

#[test]
fn bad_folders_and_settings_are_refused_by_name() {
    let tmp = scratch("folders");
    let (good, _, depth) = tum_clip(&tmp.0, "good");

    // Values that do not fit this data's images exit 1 (out of every
    // option's own range: exit 2, bad_command_lines_exit_2_naming_the_option).
    let a = run(&good, &["--fx", "5.354"]);
    expect(
        "implausible focal length for 640x480 (--fx 5.354)",
        &a,
        1,
        &["fx = 5.354"],
    );
    let a = run(&good, &["--cy", "1e9"]);
    expect("absurd principal point (--cy 1e9)", &a, 1, &["cy"]);
    let a = run(&good, &["--depth-min", "5"]);
    expect(
        "depth minimum beyond the preset's maximum (4 m)",
        &a,
        1,
        &["depth range"],
    );

    let empty = tmp.0.join("empty");
    std::fs::create_dir_all(&empty).expect("dir");
    let a = run(&empty, &[]);
    expect("empty folder", &a, 1, &["empty", "empty"]);

    let photos = tmp.0.join("holiday_photos");
    std::fs::create_dir_all(&photos).expect("dir");
    std::fs::write(photos.join("beach.jpg"), b"not really").expect("write");
    std::fs::write(photos.join("notes.txt"), b"hello").expect("write");
    let a = run(&photos, &[]);
    expect(
        "folder in no known layout",
        &a,
        1,
        &["holiday_photos", "unrecognised dataset layout", "beach.jpg"],
    );

    let (missing, _, _) = tum_clip(&tmp.0, "missing");
    std::fs::remove_file(missing.join(&depth[2])).expect("remove");
    let a = run(&missing, &[]);
    expect(
        "file listed in an index is missing (that frame is skipped)",
        &a,
        3,
        &[
            "frame 2 skipped",
            depth[2].as_str(),
            "is missing (listed in depth.txt)",
        ],
    );

    let (bad_gt, _, _) = tum_clip(&tmp.0, "bad_gt");
    let gt = std::fs::read_to_string(bad_gt.join("groundtruth.txt")).expect("gt");
    let mut lines: Vec<&str> = gt.lines().collect();
    lines.insert(5, "1341841873.5 1.0 2.0 oops 0 0 0 1");
    std::fs::write(bad_gt.join("groundtruth.txt"), lines.join("\n")).expect("write");
    let a = run(&bad_gt, &[]);
    expect(
        "malformed ground-truth line",
        &a,
        1,
        &["groundtruth.txt, line 6", "oops"],
    );

    // Nothing readable at all.
    let (all_bad, colour, _) = tum_clip(&tmp.0, "all_bad");
    for c in &colour {
        std::fs::write(all_bad.join(c), b"garbage").expect("write");
    }
    let outputs = ["t.txt", "map.ply", "mesh.glb", "s.slam"].map(|f| all_bad.join(f));
    let [t, ply, mesh, session] = outputs.each_ref().map(|p| p.to_str().expect("utf-8"));
    let a = run(
        &all_bad,
        &[
            "--trajectory",
            t,
            "--ply",
            ply,
            "--mesh",
            mesh,
            "--save",
            session,
        ],
    );
    expect(
        "no readable frame",
        &a,
        1,
        &["no frame of the sequence could be read"],
    );
    // Nothing tracked: no empty map, mesh or trajectory passed off as a result.
    for path in &outputs {
        assert!(
            !path.exists(),
            "{} written by a run that did nothing",
            path.display()
        );
    }

    // And the good folder runs clean.
    let a = run(&good, &[]);
    assert_eq!(a.code, 0, "{}", a.stderr);
}

#[test]
fn lost_and_recovered_frames_are_reported() {
    let tmp = scratch("lost");
    let (dir, _, depth) = tum_clip(&tmp.0, "rgbd_dataset_freiburg3_blank");
    let blank = DynamicImage::ImageLuma16(image::ImageBuffer::from_pixel(
        640,
        480,
        image::Luma([0u16]),
    ));
    std::fs::write(dir.join(&depth[2]), png(&blank)).expect("write");
    let a = run(&dir, &[]);
    eprintln!("{}{}", a.stderr, a.stdout);
    assert_eq!(a.code, 0, "{}", a.stderr);
    assert!(
        a.stderr.contains("frame 2 (")
            && a.stderr
                .contains("lost: too-few-inliers (map kept, frame not fused)"),
        "{}",
        a.stderr
    );
    assert!(
        a.stderr.contains("frame 3 (")
            && a.stderr
                .contains("recovered: re-acquired against the map after 1 lost frame(s)"),
        "{}",
        a.stderr
    );
    assert!(
        a.stdout.contains("2 tracked, 1 lost, 1 recovered"),
        "{}",
        a.stdout
    );
}

#[test]
fn bad_command_lines_exit_2_naming_the_option() {
    let tmp = scratch("usage");
    let (good, _, _) = tum_clip(&tmp.0, "good");
    let gt = good.join("groundtruth.txt");
    let (d, g) = (good.to_str().expect("utf-8"), gt.to_str().expect("utf-8"));
    let cases: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "unknown tracker",
            vec!["run", d, "--tracker", "foo"],
            vec!["--tracker", "foo", "icp, rgb, joint"],
        ),
        (
            "unknown preset",
            vec!["run", d, "--preset", "kinect"],
            vec!["--preset", "kinect", "icl-nuim"],
        ),
        (
            "non-finite intrinsics",
            vec!["run", d, "--fx", "NaN"],
            vec!["--fx", "finite"],
        ),
        (
            "not a number",
            vec!["run", d, "--cy", "abc"],
            vec!["--cy", "abc"],
        ),
        (
            "negative ICP weight",
            vec!["run", d, "--icp-weight", "-1"],
            vec!["--icp-weight", ">= 0"],
        ),
        (
            "infinite ICP weight",
            vec!["run", d, "--icp-weight", "inf"],
            vec!["--icp-weight", "finite"],
        ),
        (
            "stride 0",
            vec!["run", d, "--stride", "0"],
            vec!["--stride", "0"],
        ),
        (
            "count 0",
            vec!["run", d, "--count", "0"],
            vec!["--count", "0"],
        ),
        (
            "surfel budget 0",
            vec!["run", d, "--max-surfels", "0"],
            vec!["--max-surfels"],
        ),
        (
            "negative first frame",
            vec!["run", d, "--first", "-1"],
            vec!["--first"],
        ),
        (
            "unknown option",
            vec!["run", d, "--colour"],
            vec!["--colour"],
        ),
        ("missing dataset", vec!["run"], vec!["<DATASET>"]),
        ("unknown command", vec!["fly"], vec!["fly"]),
        (
            "bench: unknown tracker",
            vec!["bench", d, "--tracker", "foo"],
            vec!["--tracker"],
        ),
        (
            "eval: unknown association",
            vec!["eval", g, g, "--associate", "nearest"],
            vec!["--associate", "time, id, order"],
        ),
        (
            "eval: negative --max-dt",
            vec!["eval", g, g, "--max-dt", "-0.1"],
            vec!["--max-dt", ">= 0"],
        ),
        (
            "eval: plot format",
            vec!["eval", g, g, "--plot", "out.jpg"],
            vec!["--plot", ".svg or .png"],
        ),
        ("eval: one file", vec!["eval", g], vec!["<GROUND_TRUTH>"]),
    ];
    for (case, args, needles) in cases {
        expect(case, &cli(&args), 2, &needles);
    }
    // Negative numbers are values, not options: --fy -480 gets as far as
    // the camera check (a negative fy is valid; cx = -1e9 is not, for this image).
    let a = run(&good, &["--count", "2", "--fy", "-480", "--cx", "-1e9"]);
    expect("negative numbers as values", &a, 1, &["cx"]);
    // Help is not an error.
    let a = cli(&["run", "--help"]);
    assert_eq!(a.code, 0, "{}", a.stderr);
    for default in [
        "[default: the preset's: joint for icl-nuim, icp for the others]",
        "[default: 3]",
        "[default: 4000000]",
        "--depth-max <DEPTH_MAX>",
        "4 tum-fr1/tum-fr2/tum-fr3/7-scenes, 8 icl-nuim, 5 realsense-d400/stray-lidar]",
        "-480 icl-nuim",
    ] {
        assert!(
            a.stdout.contains(default),
            "help lacks {default:?}:\n{}",
            a.stdout
        );
    }
}

/// Every numeric option of every command with a bad value, and every output
/// file with an extension of no format (as `--option=value`, so that a
/// value like `-inf` is not read as an option): exit 2, the option named, decided
/// before any file is read (the dataset path does not exist: reading it
/// first would exit 1). The exit-code table in docs/cli.md states this rule.
#[test]
fn every_numeric_option_and_output_extension_exits_2_before_reading() {
    let tmp = scratch("options");
    let (good, _, _) = tum_clip(&tmp.0, "good");
    let gt = good.join("groundtruth.txt");
    let g = gt.to_str().expect("utf-8");
    let nowhere = tmp.0.join("no_such_folder");
    let n = nowhere.to_str().expect("utf-8");
    let ply = tmp.0.join("no_such_map.ply");
    let p = ply.to_str().expect("utf-8");
    // (command line, the option stderr must name)
    let mut cases: Vec<(Vec<&str>, &str)> = Vec::new();
    for command in ["run", "bench"] {
        for (option, values) in [
            ("--fx", &["0", "0.5", "-0.5", "2e6", "NaN", "abc"][..]),
            ("--fy", &["0", "inf", "x"][..]),
            ("--cx", &["NaN", "inf", "x"][..]),
            ("--cy", &["-inf", "x"][..]),
            ("--depth-scale", &["0", "-5000", "NaN", "x"][..]),
            ("--depth-min", &["-0.1", "NaN", "x"][..]),
            ("--depth-max", &["0", "-1", "inf", "x"][..]),
            ("--max-surfels", &["0", "-1", "1.5", "x"][..]),
            ("--icp-weight", &["-1", "inf", "x"][..]),
            ("--noise", &["1", "1,2,3,4,5,6,7", "loud"][..]),
            ("--min-noise-weight", &["-0.5", "NaN"][..]),
        ] {
            for value in values {
                cases.push((vec![command, n, leak(format!("{option}={value}"))], option));
            }
        }
        cases.push((
            vec![command, n, "--depth-min", "5", "--depth-max", "1"],
            "--depth-min",
        ));
        cases.push((
            vec![command, n, "--depth-min", "2", "--depth-max", "2"],
            "--depth-max",
        ));
    }
    for (option, values) in [
        ("--first", &["-1", "1.5", "x"][..]),
        ("--count", &["0", "-3", "x"][..]),
        ("--stride", &["0", "-2", "x"][..]),
        ("--voxel-size", &["0", "-0.01", "2", "NaN", "x"][..]),
    ] {
        for value in values {
            cases.push((vec!["run", n, leak(format!("{option}={value}"))], option));
        }
    }
    for value in ["0", "-1", "x"] {
        cases.push((
            vec!["bench", n, leak(format!("--frames={value}"))],
            "--frames",
        ));
    }
    for value in ["0", "2", "-0.01", "x"] {
        cases.push((
            vec![
                "mesh",
                p,
                "-o",
                "m.glb",
                leak(format!("--voxel-size={value}")),
            ],
            "--voxel-size",
        ));
    }
    for value in ["NaN", "x"] {
        cases.push((
            vec![
                "mesh",
                p,
                "-o",
                "m.glb",
                leak(format!("--min-confidence={value}")),
            ],
            "--min-confidence",
        ));
    }
    for value in ["-0.1", "NaN", "x"] {
        cases.push((
            vec!["eval", g, g, leak(format!("--max-dt={value}"))],
            "--max-dt",
        ));
    }
    // Output files whose extension names no format.
    for ext in ["stl", "gltf", "txt", ""] {
        let mesh = format!("out.{ext}");
        cases.push((vec!["run", n, "--mesh", leak(mesh.clone())], "--mesh"));
        cases.push((vec!["mesh", p, "-o", leak(mesh)], "--output"));
    }
    for ext in ["jpg", "pdf", "svgz"] {
        cases.push((
            vec!["eval", g, g, "--plot", leak(format!("out.{ext}"))],
            "--plot",
        ));
    }
    for (args, option) in &cases {
        let a = cli(args);
        let case = args.join(" ");
        expect(&case, &a, 2, &[option]);
        assert!(
            !a.stderr.contains("no_such"),
            "{case}: a file was looked at before the command line was judged:\n{}",
            a.stderr
        );
    }
    eprintln!("{} bad command lines, each exit 2", cases.len());
}

/// Every output extension that names a format is written (exit 0).
#[test]
fn every_output_extension_with_a_format_is_written() {
    let tmp = scratch("outputs");
    let (good, _, _) = tum_clip(&tmp.0, "good");
    let out = |name: &str| tmp.0.join(name);
    let mut args: Vec<String> = vec!["run".into(), good.display().to_string(), "--quiet".into()];
    for (flag, file) in [
        ("--trajectory", "t.txt"),
        ("--online-trajectory", "o.txt"),
        ("--ply", "map.ply"),
        ("--mesh", "mesh.glb"),
    ] {
        args.push(flag.into());
        args.push(out(file).display().to_string());
    }
    let a = cli(&args);
    assert_eq!(a.code, 0, "{}", a.stderr);
    for ext in ["ply", "obj", "glb"] {
        let mesh = out(&format!("m.{ext}"));
        let a = cli(&[
            "mesh".as_ref(),
            out("map.ply").as_os_str(),
            "-o".as_ref(),
            mesh.as_os_str(),
        ]);
        assert_eq!(a.code, 0, "mesh -o .{ext}: {}", a.stderr);
        assert!(
            std::fs::metadata(&mesh).is_ok_and(|m| m.len() > 0),
            ".{ext} written"
        );
    }
    let gt = good.join("groundtruth.txt");
    for ext in ["svg", "png"] {
        let plot = out(&format!("plot.{ext}"));
        let a = cli(&[
            "eval".as_ref(),
            gt.as_os_str(), // the ground truth against itself: the plot is what is tested
            gt.as_os_str(),
            "--plot".as_ref(),
            plot.as_os_str(),
        ]);
        assert_eq!(a.code, 0, "eval --plot .{ext}: {}", a.stderr);
        assert!(
            std::fs::metadata(&plot).is_ok_and(|m| m.len() > 0),
            ".{ext} written"
        );
    }
}

/// A `&'static str` for the case table (a test process; freed at exit).
fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}
