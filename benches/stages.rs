//! Per-stage benchmarks on real 640x480 frames (TUM fr3/teddy from
//! ../shared/data; the synthetic room when that is absent) and on a map of
//! realistic size (the model after the first `MAP_FRAMES` frames).
//!
//! `cargo bench --bench stages` (add `-- <name>` to run one group).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
// a test, bench or example fails loudly

// `criterion_group!` generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::{DAffine3, Vec3};
use std::path::PathBuf;
use surfel_slam::dataset::Sequence;
use surfel_slam::features::{FeatureConfig, SparseEstimator};
use surfel_slam::fusion::{DepthTiles, Integrator, Measured, Prediction};
use surfel_slam::preprocess::{back_project_into, normals_into, FramePyramid};
use surfel_slam::se3::RigidF32;
use surfel_slam::synthetic::{self, NoiseModel, Scene};
use surfel_slam::track::icp::icp_step;
use surfel_slam::track::model_points::ModelPoints;
use surfel_slam::track::rgb::RgbWorkspace;
use surfel_slam::{CameraPreset, Pipeline, RgbdFrame, SlamConfig};

/// Frames fused before the map-sized benchmarks.
const MAP_FRAMES: usize = 60;

/// PNG bytes of one frame: colour, depth.
type PngPair = (Vec<u8>, Vec<u8>);

/// PNG bytes of consecutive frames, and the matching config.
fn frames() -> (SlamConfig, Vec<PngPair>) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/tum_fr3_teddy");
    if let Ok(sequence) = Sequence::open(&dir) {
        let bytes = sequence
            .frames
            .iter()
            .take(MAP_FRAMES + 1)
            .map(|f| {
                let read = |name: &str| std::fs::read(dir.join(name)).expect("readable frame");
                (read(f.colour.as_deref().expect("colour")), read(&f.depth))
            })
            .collect();
        return (SlamConfig::from_preset(CameraPreset::TumFr3), bytes);
    }
    eprintln!("../shared/data absent: benchmarking the synthetic room instead");
    let k = synthetic::default_intrinsics();
    let scene = Scene::room();
    let bytes = synthetic::trajectory(MAP_FRAMES + 1)
        .iter()
        .enumerate()
        .map(|(i, pose)| {
            synthetic::render(&scene, &k, pose, &NoiseModel::kinect(), i as u64)
                .to_png_bytes()
                .expect("encodable frame")
        })
        .collect();
    let mut config = SlamConfig::from_preset(CameraPreset::TumFr3);
    config.intrinsics = k;
    config.depth.scale = synthetic::DEPTH_UNITS_PER_METRE;
    (config, bytes)
}

/// Everything a stage needs: the map after `MAP_FRAMES` frames, its last
/// pose, and the next frame decoded.
struct Fixture {
    config: SlamConfig,
    bytes: Vec<PngPair>,
    slam: Pipeline,
    pose: DAffine3,
    next: RgbdFrame,
}

fn fixture() -> Fixture {
    let (config, bytes) = frames();
    let mut slam = Pipeline::new(config.clone()).expect("valid config");
    for (i, (c, d)) in bytes.iter().take(MAP_FRAMES).enumerate() {
        slam.push_png(c, d, i as f64).expect("decodable frame");
    }
    let pose = slam.trajectory().last().map(|p| p.1).unwrap_or_default();
    let (c, d) = &bytes[MAP_FRAMES];
    let next = RgbdFrame::from_png_bytes(c, d, &config.depth).expect("decodable frame");
    Fixture {
        config,
        bytes,
        slam,
        pose,
        next,
    }
}

fn stages(c: &mut Criterion) {
    let f = fixture();
    let k = f.config.intrinsics;
    eprintln!(
        "map: {} surfels after {MAP_FRAMES} frames, {} rayon threads",
        f.slam.map().len(),
        rayon::current_num_threads()
    );

    let (colour, depth) = &f.bytes[MAP_FRAMES];
    c.bench_function("decode colour+depth png", |b| {
        b.iter(|| RgbdFrame::from_png_bytes(colour, depth, &f.config.depth).expect("decodes"));
    });

    // Built here because criterion skips the closures of filtered-out benchmarks.
    let mut pyramid = FramePyramid::new(&k, &f.config.preprocess);
    pyramid.build(&f.next, &f.config.preprocess, &f.config.tracker.noise);
    c.bench_function("preprocess (bilateral, pyramid, vertices, normals)", |b| {
        b.iter(|| pyramid.build(&f.next, &f.config.preprocess, &f.config.tracker.noise));
    });
    let unfiltered = surfel_slam::preprocess::PreprocessConfig {
        bilateral: false,
        ..f.config.preprocess
    };
    let mut plain = FramePyramid::new(&k, &unfiltered);
    c.bench_function("preprocess without bilateral", |b| {
        b.iter(|| plain.build(&f.next, &unfiltered, &f.config.tracker.noise));
    });
    let level0 = &pyramid.levels[0];
    let mut normals = vec![glam::Vec3::ZERO; k.pixel_count()];
    c.bench_function("normal map 640x480", |b| {
        b.iter(|| normals_into(&level0.vertices, k.width, &mut normals));
    });

    let fusion = f.config.fusion;
    let far = f.config.depth.max_m;
    let mut prediction = Prediction::new(true);
    let map = f.slam.map();
    let include = |i| fusion.predicts(map, i, MAP_FRAMES as u32);
    // The prediction shows what the last fused frame measured from `pose`.
    let (c_last, d_last) = &f.bytes[MAP_FRAMES - 1];
    let last = RgbdFrame::from_png_bytes(c_last, d_last, &f.config.depth).expect("decodable frame");
    let mut last_pyramid = FramePyramid::new(&k, &f.config.preprocess);
    last_pyramid.build(&last, &f.config.preprocess, &f.config.tracker.noise);
    let mut tiles = DepthTiles::default();
    tiles.build(&last_pyramid.levels[0].vertices, k.width);
    let measured = Measured {
        vertices: &last_pyramid.levels[0].vertices,
        tiles: &tiles,
    };
    let band = (fusion.depth_gate_m, far);
    prediction.render(map, &f.pose, &k, band, measured, 0..u32::MAX, include);
    c.bench_function("prediction (map-sized)", |b| {
        b.iter(|| prediction.render(map, &f.pose, &k, band, measured, 0..u32::MAX, include));
    });

    let camera_from_world = RigidF32::from_affine(&f.pose.inverse());
    let gates = f.config.tracker.gates;
    let mut sources = ModelPoints::default();
    c.bench_function("icp sources (gather the prediction's pixels)", |b| {
        b.iter(|| sources.gather_from(&prediction));
    });
    for (level, target) in pyramid.levels.iter().enumerate() {
        c.bench_function(&format!("icp iteration level {level}"), |b| {
            b.iter(|| {
                icp_step(
                    &sources,
                    1 << level,
                    target,
                    &camera_from_world,
                    &gates,
                    None,
                )
            });
        });
    }

    let photometric = f.config.tracker.photometric.clone();
    let mut rgb = RgbWorkspace::default();
    c.bench_function("photometric prepare (gradients, reference pixels)", |b| {
        b.iter(|| rgb.prepare(&pyramid, &prediction, &photometric));
    });
    for (level, target) in pyramid.levels.iter().enumerate() {
        c.bench_function(&format!("photometric iteration level {level}"), |b| {
            b.iter(|| rgb.step(level, target, &camera_from_world, &photometric));
        });
    }

    let mut integrator = Integrator::default();
    c.bench_function("fusion (map-sized)", |b| {
        b.iter_batched(
            || {
                // A clone has no spare capacity; the pipeline's map does.
                let mut m = map.clone();
                m.reserve(k.pixel_count());
                m
            },
            |mut m| {
                integrator.integrate(
                    &mut m,
                    &pyramid,
                    &k,
                    &f.pose,
                    (MAP_FRAMES as u32, fusion.active_at(MAP_FRAMES as u32)),
                    &fusion,
                    far,
                );
                m
            },
            BatchSize::LargeInput,
        );
    });
}

/// The sparse feature estimate (src/features): per-frame preparation, and
/// on demand corner detection and description, matching and RANSAC between
/// frames 5 apart.
fn sparse(c: &mut Criterion) {
    let (config, bytes) = frames();
    let k = config.intrinsics;
    let views: Vec<(Vec<u8>, Vec<Vec3>)> = [MAP_FRAMES - 5, MAP_FRAMES]
        .iter()
        .map(|&i| {
            let (colour, depth) = &bytes[i];
            let frame = RgbdFrame::from_png_bytes(colour, depth, &config.depth).expect("decodes");
            let mut vertices = vec![Vec3::ZERO; k.pixel_count()];
            back_project_into(&k, &frame.depth_m, &mut vertices);
            (frame.rgb, vertices)
        })
        .collect();
    let mut sparse = SparseEstimator::new(FeatureConfig::default()).expect("config");
    let (rgb, vertices) = &views[0];
    sparse
        .keep_frame(rgb, vertices, k.width, k.height)
        .expect("keeps");
    sparse.current_becomes_reference();
    let (rgb, vertices) = &views[1];
    c.bench_function("sparse keep_frame: copy (every frame)", |b| {
        b.iter(|| {
            sparse
                .keep_frame(rgb, vertices, k.width, k.height)
                .expect("keeps")
        });
    });
    c.bench_function(
        "sparse keep_frame, then prepare + detect + describe (on demand)",
        |b| {
            b.iter(|| {
                sparse
                    .keep_frame(rgb, vertices, k.width, k.height)
                    .expect("keeps");
                sparse.current().len()
            });
        },
    );
    c.bench_function(
        "sparse estimate: keep_frame, prepare + detect the current frame, match, RANSAC (on demand)",
        |b| {
            b.iter(|| {
                sparse
                    .keep_frame(rgb, vertices, k.width, k.height)
                    .expect("keeps");
                sparse.estimate()
            });
        },
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = stages, sparse
}
criterion_main!(benches);
