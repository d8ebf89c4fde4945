//! `preprocess::back_project_into` (natively in blocks of eight pixels, in
//! wasm four at a time in simd128) gives `Intrinsics::back_project`'s bits.

use glam::Vec3;
use surfel_slam::camera::Intrinsics;
use surfel_slam::preprocess::back_project_into;

#[test]
fn back_projection_gives_the_bits_of_intrinsics_back_project_at_every_pixel() {
    // 61 columns: blocks of eight and a scalar tail; some pixels without depth.
    let k = Intrinsics::new(523.1, 517.9, 30.7, 20.3, 61, 41);
    let depth: Vec<f32> = (0..k.pixel_count())
        .map(|i| match i % 7 {
            0 => 0.0,
            3 => -1.0,
            _ => 0.37 + 0.013 * (i % 101) as f32,
        })
        .collect();
    let mut out = vec![Vec3::splat(9.0); k.pixel_count()];
    back_project_into(&k, &depth, &mut out);
    for (i, (&d, &o)) in depth.iter().zip(&out).enumerate() {
        let (u, v) = ((i % k.width) as f32, (i / k.width) as f32);
        let expected = if d > 0.0 {
            k.back_project(u, v, d)
        } else {
            Vec3::ZERO
        };
        assert_eq!(
            o.to_array().map(f32::to_bits),
            expected.to_array().map(f32::to_bits),
            "pixel {i}"
        );
    }
}
