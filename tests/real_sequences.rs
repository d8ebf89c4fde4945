//! Accuracy on the real sequences in ../shared/data against their ground truth.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

mod common;

use common::{lost_count, run_dataset, shared_dataset};
use surfel_slam::eval::ate;
use surfel_slam::mesh::write_surfel_ply;

#[test]
fn icl_nuim_office_kt0_is_sub_millimetre() {
    let Some(dir) = shared_dataset("icl_office_kt0") else {
        return;
    };
    let (slam, sequence, reports) = run_dataset(&dir);
    assert_eq!(reports.len(), 150);
    assert_eq!(lost_count(&reports), 0);
    let a = ate(slam.trajectory(), &sequence.ground_truth, 0.02).expect("ate");
    eprintln!(
        "ICL office kt0: ATE {:.4} cm over {} poses, {} surfels",
        a.rmse_m * 100.0,
        a.pairs,
        slam.map().len()
    );
    assert!(a.rmse_m <= 0.001, "ATE {} m", a.rmse_m);
    let surfels = slam.map().len();
    assert!((100_000..3_000_000).contains(&surfels), "{surfels} surfels");
    assert!(slam.map().all_finite());
    let ply = write_surfel_ply(slam.map());
    assert!(ply.len() > surfels * 30);
}

#[test]
fn tum_fr3_teddy_geometry_only_is_centimetre_level() {
    let Some(dir) = shared_dataset("tum_fr3_teddy") else {
        return;
    };
    let (slam, sequence, reports) = run_dataset(&dir);
    assert_eq!(lost_count(&reports), 0);
    let a = ate(slam.trajectory(), &sequence.ground_truth, 0.02).expect("ate");
    eprintln!(
        "TUM fr3/teddy: ATE {:.3} cm over {} poses",
        a.rmse_m * 100.0,
        a.pairs
    );
    // The bar is 5 cm; 2 cm catches regressions from today's ~1 cm.
    assert!(a.rmse_m <= 0.02, "ATE {} m", a.rmse_m);
    assert!(slam.map().all_finite());
}
