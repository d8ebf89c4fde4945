//! Does the keyframe lookup find the right old place on a real revisit?
//! Judged by the dataset's ground truth, for the library's fern code and
//! for other codes a real sensor supports.
//!
//! Every frame of the sequence is reduced as the pipeline reduces it for
//! the ferns (its pyramid's colour and level-0 depth, block means to the
//! 80x60 small image; block-mean level-0 normals beside them). At each
//! global look (every `--every` frames from `--min-age` on, as the global
//! loop check) the frames older than `--min-age` frames are sorted by
//! their true relation to the current frame:
//!
//! - *right*: true camera centres < 30 cm and viewing directions < 20
//!   degrees apart, and at least half of each small depth image lands on
//!   the other's surfaces (5 cm + 5 %) when moved by the true poses;
//! - *wrong*: >= 30 cm or >= 20 degrees apart and less than half overlap
//!   (the rest, near but barely overlapping, counts as neither).
//!
//! Per code (`Encoding`), two tables:
//!
//! 1. Every old frame as a candidate (separation alone): per look the best
//!    right and best wrong dissimilarity and how many wrong frames rank
//!    before the best right one.
//! 2. The database as the pipeline builds it (a frame is added when every
//!    keyframe is more dissimilar than `add_above`; every frame counts as
//!    fused) and the lookup as the global check does it (keyframes older
//!    than the window, at most `limit` dissimilar, the 3 most similar
//!    tried): is a right keyframe among those tried, and how many wrong
//!    ones come first.
//!
//! `cargo run --release --example fern_retrieval -- ../shared/data/7scenes_redkitchen_even [--every 10] [--min-age 200] [--detail] [--blur 2] [--trajectory estimate.txt]`
//! (`--trajectory`: a run's estimate, TUM format, one pose per frame: the
//! drift a closure onto the nearest old frame would correct), or
//! `synthetic-loop` in place of the folder: the synthetic room's loop path,
//! then its first 160 views again 5 cm and 4 degrees off the path.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use glam::{DAffine3, Vec3};
use surfel_slam::dataset::trajectory::parse_tum;
use surfel_slam::dataset::{read_frame, Sequence};
use surfel_slam::loop_closure::ferns::{FernConfig, FernDatabase, BAD_CODE};
use surfel_slam::preprocess::FramePyramid;
use surfel_slam::random::SplitMix;
use surfel_slam::se3::{exp, motion_magnitude};
use surfel_slam::synthetic::{self, loop_pose, NoiseModel, Scene};
use surfel_slam::{Intrinsics, RgbdFrame, SlamConfig};

/// Right: nearer than this, metres ...
const NEAR_M: f64 = 0.30;
/// ... and this, degrees (angle between the optical axes) ...
const NEAR_DEG: f64 = 20.0;
/// ... and at least this overlap of the small depth images both ways.
const RIGHT_OVERLAP: f32 = 0.5;
/// Candidates the global check tries (`RelocaliseConfig::candidates`).
const TRIED: usize = 3;

/// A frame as the ferns see it: the small image.
struct Small {
    rgb: Vec<[u8; 3]>,
    depth: Vec<f32>,
    /// Block-mean unit normals facing the camera (camera frame), `ZERO`
    /// where fewer than half of the block's normals are defined.
    normal: Vec<Vec3>,
    /// The library's own fern codes of the frame (`None`: no depth).
    library_codes: Vec<Option<u16>>,
}

/// One value a fern can test at its pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Channel {
    Red,
    Green,
    Blue,
    Depth,
    NormalX,
    NormalY,
    NormalZ,
    /// A colour channel divided by its mean over the frame's measured
    /// blocks (exposure and white balance cancel), times 128.
    MeanRed,
    MeanGreen,
    MeanBlue,
    /// Rank (0..1) of the block's colour channel among the frame's
    /// measured blocks.
    RankRed,
    RankGreen,
    RankBlue,
    /// Rank (0..1) of the block's grey level among the frame's measured blocks.
    RankGrey,
}

impl Channel {
    /// Range the random thresholds are drawn from.
    fn range(self) -> (f32, f32) {
        match self {
            Self::Red | Self::Green | Self::Blue => (0.0, 256.0),
            Self::MeanRed | Self::MeanGreen | Self::MeanBlue => (0.0, 256.0),
            Self::Depth => (0.4, 4.5),
            Self::NormalX | Self::NormalY => (-1.0, 1.0),
            Self::NormalZ => (-1.0, 0.0),
            Self::RankRed | Self::RankGreen | Self::RankBlue | Self::RankGrey => (0.0, 1.0),
        }
    }
}

/// The library's code (`FernDatabase::encode`).
const LIBRARY: &str = "rgb+depth (library)";

/// A code: the channels each fern tests (one bit each), in fern order.
struct Encoding {
    name: &'static str,
    channels: Vec<Channel>,
    /// Tests the channels blurred (`--blur`): tolerant to small shifts of
    /// the view.
    blurred: bool,
}

fn encodings() -> Vec<Encoding> {
    use Channel::*;
    let e = |name, channels: &[Channel]| Encoding {
        name,
        channels: channels.to_vec(),
        blurred: false,
    };
    let b = |name, channels: &[Channel]| Encoding {
        name,
        channels: channels.to_vec(),
        blurred: true,
    };
    vec![
        e(LIBRARY, &[Red, Green, Blue, Depth]),
        e("depth x4", &[Depth, Depth, Depth, Depth]),
        e("depth+normal", &[Depth, NormalX, NormalY, NormalZ]),
        e("depth x2+normal xy", &[Depth, Depth, NormalX, NormalY]),
        e("mean-rgb+depth", &[MeanRed, MeanGreen, MeanBlue, Depth]),
        e("rank-rgb+depth", &[RankRed, RankGreen, RankBlue, Depth]),
        e(
            "rank-grey+depth+normal xy",
            &[RankGrey, Depth, NormalX, NormalY],
        ),
        e(
            "mean-rgb+depth+normal",
            &[
                MeanRed, MeanGreen, MeanBlue, Depth, NormalX, NormalY, NormalZ,
            ],
        ),
        b("blurred rgb+depth", &[Red, Green, Blue, Depth]),
        b(
            "blurred depth x2+normal xy",
            &[Depth, Depth, NormalX, NormalY],
        ),
        b(
            "blurred mean-rgb+depth",
            &[MeanRed, MeanGreen, MeanBlue, Depth],
        ),
        b(
            "blurred rank-grey+depth+normal xy",
            &[RankGrey, Depth, NormalX, NormalY],
        ),
    ]
}

/// Per small pixel, the value of every channel (`NaN` where no depth).
struct Values {
    per_channel: Vec<Vec<f32>>,
    /// The same, each the mean of its measured neighbours within the blur
    /// radius (`NaN` where the centre has no depth).
    blurred: Vec<Vec<f32>>,
}

const ALL: [Channel; 14] = [
    Channel::Red,
    Channel::Green,
    Channel::Blue,
    Channel::Depth,
    Channel::NormalX,
    Channel::NormalY,
    Channel::NormalZ,
    Channel::MeanRed,
    Channel::MeanGreen,
    Channel::MeanBlue,
    Channel::RankRed,
    Channel::RankGreen,
    Channel::RankBlue,
    Channel::RankGrey,
];

fn slot(c: Channel) -> usize {
    ALL.iter().position(|&a| a == c).unwrap()
}

fn ranks(values: &[f32], valid: &[bool]) -> Vec<f32> {
    let mut order: Vec<usize> = (0..values.len()).filter(|&i| valid[i]).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
    let mut out = vec![f32::NAN; values.len()];
    let n = order.len().max(2) as f32 - 1.0;
    // Ties share the mean rank: equal colours stay equal.
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && values[order[j + 1]] == values[order[i]] {
            j += 1;
        }
        let r = 0.5 * (i + j) as f32 / n;
        for &k in &order[i..=j] {
            out[k] = r;
        }
        i = j + 1;
    }
    out
}

/// Mean of the non-`NaN` values within `radius` (a square), `NaN` where
/// the centre is `NaN`.
fn box_blur(v: &[f32], w: usize, h: usize, radius: usize) -> Vec<f32> {
    let mut out = vec![f32::NAN; v.len()];
    for y in 0..h {
        for x in 0..w {
            if v[y * w + x].is_nan() {
                continue;
            }
            let (mut sum, mut n) = (0.0f32, 0u32);
            for yy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
                for xx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                    let a = v[yy * w + xx];
                    if !a.is_nan() {
                        sum += a;
                        n += 1;
                    }
                }
            }
            out[y * w + x] = sum / n as f32;
        }
    }
    out
}

fn values_of(s: &Small, w: usize, h: usize, radius: usize) -> Values {
    let n = s.depth.len();
    let valid: Vec<bool> = s.depth.iter().map(|&z| z > 0.0).collect();
    let channel = |c: usize| -> Vec<f32> { s.rgb.iter().map(|p| f32::from(p[c])).collect() };
    let (r, g, b) = (channel(0), channel(1), channel(2));
    let grey: Vec<f32> = (0..n)
        .map(|i| 0.299 * r[i] + 0.587 * g[i] + 0.114 * b[i])
        .collect();
    let mean_norm = |v: &[f32]| -> Vec<f32> {
        let (sum, count) = v
            .iter()
            .zip(&valid)
            .filter(|(_, &ok)| ok)
            .fold((0.0f64, 0usize), |(s, c), (&x, _)| {
                (s + f64::from(x), c + 1)
            });
        let mean = (sum / count.max(1) as f64).max(1.0) as f32;
        v.iter().map(|&x| (x / mean * 128.0).min(255.0)).collect()
    };
    let normal = |f: fn(Vec3) -> f32| -> Vec<f32> {
        s.normal
            .iter()
            .map(|&n| if n == Vec3::ZERO { f32::NAN } else { f(n) })
            .collect()
    };
    let mut per_channel = vec![
        r.clone(),
        g.clone(),
        b.clone(),
        s.depth.clone(),
        normal(|n| n.x),
        normal(|n| n.y),
        normal(|n| n.z),
        mean_norm(&r),
        mean_norm(&g),
        mean_norm(&b),
        ranks(&r, &valid),
        ranks(&g, &valid),
        ranks(&b, &valid),
        ranks(&grey, &valid),
    ];
    for v in &mut per_channel {
        for (x, &ok) in v.iter_mut().zip(&valid) {
            if !ok {
                *x = f32::NAN;
            }
        }
    }
    let blurred = per_channel
        .iter()
        .map(|v| box_blur(v, w, h, radius))
        .collect();
    Values {
        per_channel,
        blurred,
    }
}

/// Ferns of one encoding: pixel and per-bit threshold.
struct Ferns {
    pixel: Vec<usize>,
    tests: Vec<Vec<(usize, f32)>>,
}

fn ferns_for(e: &Encoding, count: usize, pixels: usize, seed: u64) -> Ferns {
    let mut rng = SplitMix::new(seed);
    let mut pixel = Vec::new();
    let mut tests = Vec::new();
    for _ in 0..count {
        pixel.push((rng.next_u64() % pixels as u64) as usize);
        tests.push(
            e.channels
                .iter()
                .map(|&c| {
                    let (lo, hi) = c.range();
                    (slot(c), lo + (hi - lo) * rng.next_f32())
                })
                .collect(),
        );
    }
    Ferns { pixel, tests }
}

/// Codes of a frame (`None`: a fern whose pixel has no depth or no normal
/// where it tests one).
fn codes(ferns: &Ferns, v: &Values, blurred: bool) -> Vec<Option<u16>> {
    let channels = if blurred { &v.blurred } else { &v.per_channel };
    ferns
        .pixel
        .iter()
        .zip(&ferns.tests)
        .map(|(&p, tests)| {
            let mut code = 0u16;
            for &(slot, t) in tests {
                let x = channels[slot][p];
                if x.is_nan() {
                    return None;
                }
                code = (code << 1) | u16::from(x > t);
            }
            Some(code)
        })
        .collect()
}

/// The library's block-code dissimilarity.
fn dissimilarity(a: &[Option<u16>], b: &[Option<u16>]) -> f32 {
    let good = |c: &[Option<u16>]| c.iter().filter(|x| x.is_some()).count();
    let possible = good(a).min(good(b));
    if possible == 0 {
        return 1.0;
    }
    let same = a
        .iter()
        .zip(b)
        .filter(|(x, y)| x.is_some() && x == y)
        .count();
    (possible - same.min(possible)) as f32 / possible as f32
}

fn small_intrinsics(k: &Intrinsics, block: (usize, usize), w: usize, h: usize) -> Intrinsics {
    let (bx, by) = (block.0 as f32, block.1 as f32);
    Intrinsics::new(
        k.fx / bx,
        k.fy / by,
        (k.cx - 0.5 * (bx - 1.0)) / bx,
        (k.cy - 0.5 * (by - 1.0)) / by,
        w,
        h,
    )
}

/// Fraction of `a`'s measured blocks that land on `b`'s surfaces (5 cm +
/// 5 %) when moved by the true poses.
fn overlap(k: &Intrinsics, a: (&Small, &DAffine3), b: (&Small, &DAffine3)) -> f32 {
    let b_from_a = (b.1.inverse() * *a.1).as_affine3a();
    let (mut valid, mut landed) = (0usize, 0usize);
    for (i, &z) in a.0.depth.iter().enumerate() {
        if z <= 0.0 {
            continue;
        }
        valid += 1;
        let (u, v) = ((i % k.width) as f32, (i / k.width) as f32);
        let q = b_from_a.transform_point3(k.back_project(u, v, z));
        if q.z <= 0.0 {
            continue;
        }
        let Some(j) = k.pixel_index(k.project(q)) else {
            continue;
        };
        let zb = b.0.depth[j];
        if zb > 0.0 && (zb - q.z).abs() <= 0.05 + 0.05 * q.z {
            landed += 1;
        }
    }
    landed as f32 / valid.max(1) as f32
}

/// Truth of old frame `j` against frame `i`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Truth {
    Right,
    Wrong,
    Neither,
}

struct Relation {
    truth: Truth,
    metres: f64,
    degrees: f64,
    overlap: f32,
}

fn relation(
    k: &Intrinsics,
    frames: &[Small],
    truth: &[Option<DAffine3>],
    i: usize,
    j: usize,
) -> Option<Relation> {
    let (pi, pj) = (truth[i]?, truth[j]?);
    let (metres, _) = motion_magnitude(&(pj.inverse() * pi));
    let axis = |p: &DAffine3| p.matrix3.z_axis;
    let degrees = axis(&pi).angle_between(axis(&pj)).to_degrees();
    let ov = overlap(k, (&frames[i], &pi), (&frames[j], &pj)).min(overlap(
        k,
        (&frames[j], &pj),
        (&frames[i], &pi),
    ));
    let near = metres < NEAR_M && degrees < NEAR_DEG;
    let truth = if near && ov >= RIGHT_OVERLAP {
        Truth::Right
    } else if !near && ov < RIGHT_OVERLAP {
        Truth::Wrong
    } else {
        Truth::Neither
    };
    Some(Relation {
        truth,
        metres,
        degrees,
        overlap: ov,
    })
}

/// Block-mean unit normals of the `width x height` level-0 normals into
/// the small image's blocks.
fn block_normals(normals: &[Vec3], width: usize, height: usize, w: usize, h: usize) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; w * h];
    for v in 0..h {
        for u in 0..w {
            let (x0, x1) = (u * width / w, (u + 1) * width / w);
            let (y0, y1) = (v * height / h, (v + 1) * height / h);
            let (mut sum, mut count) = (Vec3::ZERO, 0usize);
            for y in y0..y1 {
                for n in &normals[y * width + x0..y * width + x1] {
                    if *n != Vec3::ZERO && n.is_finite() {
                        sum += *n;
                        count += 1;
                    }
                }
            }
            if 2 * count >= (x1 - x0) * (y1 - y0) && sum.length() > 1e-3 {
                out[v * w + u] = sum.normalize();
            }
        }
    }
    out
}

struct Args {
    dir: std::path::PathBuf,
    every: usize,
    min_age: usize,
    detail: bool,
    /// An estimated trajectory (TUM format, one pose per frame in order).
    trajectory: Option<std::path::PathBuf>,
    /// Blur radius of the blurred channels, small pixels.
    blur: usize,
}

fn args() -> Args {
    let mut a = Args {
        dir: std::path::PathBuf::new(),
        every: 10,
        min_age: 200,
        detail: false,
        trajectory: None,
        blur: 2,
    };
    let mut it = std::env::args().skip(1);
    while let Some(s) = it.next() {
        match s.as_str() {
            "--every" => a.every = it.next().and_then(|v| v.parse().ok()).expect("--every N"),
            "--min-age" => a.min_age = it.next().and_then(|v| v.parse().ok()).expect("--min-age N"),
            "--detail" => a.detail = true,
            "--trajectory" => a.trajectory = it.next().map(Into::into),
            "--blur" => a.blur = it.next().and_then(|v| v.parse().ok()).expect("--blur N"),
            _ => a.dir = s.into(),
        }
    }
    assert!(
        !a.dir.as_os_str().is_empty(),
        "usage: fern_retrieval <dataset or synthetic-loop> [--every N] [--min-age N] [--detail] [--blur N] [--trajectory FILE]"
    );
    a
}

/// Frames to measure, their configuration and their true poses.
struct Input {
    config: SlamConfig,
    frames: Vec<RgbdFrame>,
    truth: Vec<Option<DAffine3>>,
}

fn real_sequence(dir: &std::path::Path) -> Result<Input, Box<dyn std::error::Error>> {
    let sequence = Sequence::open(dir)?;
    let config = SlamConfig::from_preset(sequence.preset);
    let mut frames = Vec::new();
    let mut truth = Vec::new();
    for entry in &sequence.frames {
        frames.push(read_frame(dir, entry, &config.depth)?);
        truth.push(sequence.ground_truth_for(entry.timestamp, 0.02));
    }
    Ok(Input {
        config,
        frames,
        truth,
    })
}

/// The synthetic room (320x240, Kinect-like noise): one turn of the loop
/// path (240 frames), then its first 160 views again, each 5 cm and 4
/// degrees off the path (as `tests/relocalisation.rs` revisits).
fn synthetic_loop() -> Result<Input, Box<dyn std::error::Error>> {
    let k = synthetic::default_intrinsics().half();
    let mut config = SlamConfig::from_preset(surfel_slam::CameraPreset::TumFr3);
    config.intrinsics = k;
    config.depth = synthetic::depth_settings();
    let scene = Scene::room();
    let off_path = |pose: DAffine3| pose * exp(&[0.04, -0.03, 0.05, 0.03, 0.02, -0.03]);
    let poses: Vec<DAffine3> = (0..240)
        .map(|i| loop_pose(i, 240))
        .chain((0..160).map(|i| off_path(loop_pose(i, 240))))
        .collect();
    let mut frames = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        let f = synthetic::render(&scene, &k, pose, &NoiseModel::kinect(), i as u64);
        frames.push(f.to_frame(&config.depth)?);
    }
    Ok(Input {
        config,
        frames,
        truth: poses.into_iter().map(Some).collect(),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = args();
    let input = if args.dir.as_os_str() == "synthetic-loop" {
        synthetic_loop()?
    } else {
        real_sequence(&args.dir)?
    };
    let Input {
        config,
        frames: raw,
        truth,
    } = input;
    let k = config.working_intrinsics();
    let fern_config = FernConfig::default();
    let (w, h) = (fern_config.width, fern_config.height);
    let mut pyramid = FramePyramid::new(&k, &config.preprocess);
    let mut library = FernDatabase::new(fern_config)?;
    let mut frames = Vec::new();
    let mut block = (1, 1);
    for frame in &raw {
        pyramid.build(frame, &config.preprocess, &config.tracker.noise);
        let level = &pyramid.levels[0];
        library.encode(&pyramid.rgb, &level.depth, k.width, k.height)?;
        let small = library.current();
        block = small.block;
        frames.push(Small {
            rgb: small.rgb.clone(),
            depth: small.depth_m.clone(),
            normal: block_normals(&level.normals, k.width, k.height, w, h),
            library_codes: small
                .codes
                .iter()
                .map(|&c| (c != BAD_CODE).then_some(u16::from(c)))
                .collect(),
        });
    }
    drop(raw);
    let sk = small_intrinsics(&k, block, w, h);
    let n = frames.len();
    let looks: Vec<usize> = (args.min_age..n).step_by(args.every.max(1)).collect();
    println!(
        "{}: {n} frames, {} looks (every {} from {}), candidates older than {} frames",
        args.dir.display(),
        looks.len(),
        args.every,
        args.min_age,
        args.min_age
    );
    // Truth of every (look, old frame) pair, and the nearest old frame.
    let mut relations: Vec<Vec<(usize, Relation)>> = Vec::new();
    for &i in &looks {
        let old: Vec<(usize, Relation)> = (0..i - args.min_age)
            .filter_map(|j| relation(&sk, &frames, &truth, i, j).map(|r| (j, r)))
            .collect();
        relations.push(old);
    }
    println!("\nground truth: old frames per look that are right (< {NEAR_M} m, < {NEAR_DEG} deg, overlap >= {RIGHT_OVERLAP}); the nearest old frame");
    let estimate = match &args.trajectory {
        Some(path) => {
            let text = std::fs::read_to_string(path)?;
            let poses = parse_tum(&text, &path.display().to_string())?;
            assert_eq!(poses.len(), n, "one estimated pose per frame");
            Some(poses.into_iter().map(|(_, p)| p).collect::<Vec<_>>())
        }
        None => None,
    };
    // The correction a closure onto old frame j would make at frame i:
    // the estimated motion j -> i against the true one.
    let drift = |i: usize, j: usize| -> Option<(f64, f64)> {
        let est = estimate.as_ref()?;
        let (gi, gj) = (truth[i]?, truth[j]?);
        let (dt, dr) =
            motion_magnitude(&((gj.inverse() * gi).inverse() * (est[j].inverse() * est[i])));
        Some((dt * 100.0, dr.to_degrees()))
    };
    println!("look | right old frames | nearest old frame: frame, cm, deg, overlap | drift from it (estimate against truth): cm, deg");
    for (&i, rel) in looks.iter().zip(&relations) {
        let right: Vec<usize> = rel
            .iter()
            .filter(|(_, r)| r.truth == Truth::Right)
            .map(|(j, _)| *j)
            .collect();
        let nearest = rel.iter().min_by(|a, b| {
            (a.1.metres + a.1.degrees / 100.0).total_cmp(&(b.1.metres + b.1.degrees / 100.0))
        });
        let span = match (right.first(), right.last()) {
            (Some(a), Some(b)) => format!("{} ({a}..{b})", right.len()),
            _ => "0".to_string(),
        };
        let near = nearest.map_or("-".to_string(), |(j, r)| {
            let d = drift(i, *j).map_or("-".to_string(), |(cm, deg)| format!("{cm:.1}, {deg:.1}"));
            format!(
                "{j}, {:.1}, {:.1}, {:.2} | {d}",
                r.metres * 100.0,
                r.degrees,
                r.overlap
            )
        });
        println!("{i} | {span} | {near}");
    }
    let values: Vec<Values> = frames
        .iter()
        .map(|f| values_of(f, w, h, args.blur))
        .collect();
    let library_db = FernConfig::default();
    for e in encodings() {
        let ferns = ferns_for(&e, library_db.ferns, w * h, library_db.seed);
        // The library's code is read from the library itself; the
        // others are drawn here alike (one pixel, uniform thresholds).
        let all: Vec<Vec<Option<u16>>> = if e.name == LIBRARY {
            frames.iter().map(|f| f.library_codes.clone()).collect()
        } else {
            values.iter().map(|v| codes(&ferns, v, e.blurred)).collect()
        };
        report(&e, &all, &looks, &relations, &args);
    }
    Ok(())
}

fn report(
    e: &Encoding,
    all: &[Vec<Option<u16>>],
    looks: &[usize],
    relations: &[Vec<(usize, Relation)>],
    args: &Args,
) {
    let good_min = FernConfig::default().min_good_fraction;
    let usable = |c: &[Option<u16>]| {
        c.iter().filter(|x| x.is_some()).count() as f32 >= good_min * c.len() as f32
    };
    println!("\n== {} ({} bits a fern)", e.name, e.channels.len());
    // 1. Every old frame a candidate.
    let (mut with_right, mut right_first, mut below) = (0, 0, [0usize; 3]);
    let limits = [0.35f32, 0.45, 0.55];
    let mut rows = Vec::new();
    for (&i, rel) in looks.iter().zip(relations) {
        if !usable(&all[i]) {
            continue;
        }
        let d = |j: usize| dissimilarity(&all[i], &all[j]);
        let best = |t: Truth| {
            rel.iter()
                .filter(|(j, r)| r.truth == t && usable(&all[*j]))
                .map(|(j, _)| (d(*j), *j))
                .min_by(|a, b| a.0.total_cmp(&b.0))
        };
        let (right, wrong) = (best(Truth::Right), best(Truth::Wrong));
        let Some((r, rj)) = right else {
            rows.push(format!(
                "{i} | - | {}",
                wrong.map_or("-".into(), |(d, j)| format!("{d:.3} ({j})"))
            ));
            continue;
        };
        with_right += 1;
        let before = rel
            .iter()
            .filter(|(j, t)| t.truth == Truth::Wrong && usable(&all[*j]) && d(*j) < r)
            .count();
        if before == 0 {
            right_first += 1;
        }
        for (b, &l) in below.iter_mut().zip(&limits) {
            if r <= l {
                *b += 1;
            }
        }
        rows.push(format!(
            "{i} | {r:.3} ({rj}) | {} | {before}",
            wrong.map_or("-".into(), |(d, j)| format!("{d:.3} ({j})"))
        ));
    }
    println!(
        "every old frame a candidate: {with_right} looks with a right frame; right ranked first {right_first}; best right <= 0.35/0.45/0.55: {}/{}/{}",
        below[0], below[1], below[2]
    );
    if args.detail {
        println!("look | best right (frame) | best wrong (frame) | wrong before right");
        for r in rows {
            println!("{r}");
        }
    }
    // 2. The database as the pipeline builds it, looked up as the global check does.
    for (add_above, limit) in [(0.3f32, 0.45f32), (0.2, 0.35)] {
        let mut keyframes: Vec<usize> = Vec::new();
        let mut look_at = looks.iter().zip(relations).peekable();
        let (mut tried_right, mut found_right, mut wrong_first, mut any) = (0, 0, 0, 0);
        // Per look with a right old frame: `R` a right keyframe tried
        // first, `r` tried after a wrong or neither one, `.` none tried.
        let mut marks = String::new();
        let mut wrong_without_right = 0;
        let mut lines = Vec::new();
        for i in 0..all.len() {
            if let Some((&li, rel)) = look_at.peek().copied() {
                if li == i {
                    look_at.next();
                    let old: Vec<(usize, f32)> = {
                        let mut v: Vec<(usize, f32)> = keyframes
                            .iter()
                            .filter(|&&j| j + args.min_age < i)
                            .map(|&j| (j, dissimilarity(&all[i], &all[j])))
                            .filter(|&(_, d)| d <= limit)
                            .collect();
                        v.sort_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
                        v
                    };
                    let truth_of = |j: usize| {
                        rel.iter()
                            .find(|(f, _)| *f == j)
                            .map_or(Truth::Neither, |(_, r)| r.truth)
                    };
                    let right_keyframes = keyframes
                        .iter()
                        .filter(|&&j| j + args.min_age < i && truth_of(j) == Truth::Right)
                        .count();
                    if right_keyframes > 0 {
                        any += 1;
                    }
                    let tried = &old[..old.len().min(TRIED)];
                    let first_right = tried.iter().position(|&(j, _)| truth_of(j) == Truth::Right);
                    if first_right.is_some() {
                        tried_right += 1;
                    }
                    if old.iter().any(|&(j, _)| truth_of(j) == Truth::Right) {
                        found_right += 1;
                    }
                    let wrong_before = tried[..first_right.unwrap_or(tried.len())]
                        .iter()
                        .filter(|&&(j, _)| truth_of(j) == Truth::Wrong)
                        .count();
                    wrong_first += wrong_before;
                    if rel.iter().any(|(_, r)| r.truth == Truth::Right) {
                        marks.push(match first_right {
                            Some(0) => 'R',
                            Some(_) => 'r',
                            None => '.',
                        });
                    } else {
                        wrong_without_right += tried
                            .iter()
                            .filter(|&&(j, _)| truth_of(j) == Truth::Wrong)
                            .count();
                    }
                    let list: Vec<String> = tried
                        .iter()
                        .map(|&(j, d)| {
                            let t = match truth_of(j) {
                                Truth::Right => "R",
                                Truth::Wrong => "W",
                                Truth::Neither => "n",
                            };
                            format!("{j}{t} {d:.2}")
                        })
                        .collect();
                    lines.push(format!(
                        "{i} | right keyframes {right_keyframes} | tried: {}",
                        list.join(", ")
                    ));
                }
            }
            if !usable(&all[i]) {
                continue;
            }
            let novel = keyframes
                .iter()
                .all(|&j| dissimilarity(&all[i], &all[j]) > add_above);
            if novel {
                keyframes.push(i);
            }
        }
        println!(
            "database (add above {add_above}, limit {limit}): {} keyframes; looks with a right old keyframe {any}; a right one within the limit {found_right}, among the {TRIED} tried {tried_right}; wrong ones tried before a right one (or instead) {wrong_first}, of them at looks without a right old frame {wrong_without_right}\n  looks with a right old frame: {marks}",
            keyframes.len()
        );
        if args.detail {
            for l in lines {
                println!("  {l}");
            }
        }
    }
}
