//! `surfel-slam mesh <map.ply> -o out.{glb,ply,obj}`: a saved surfel map
//! (a sphere of surfels written by the library's PLY writer) becomes a mesh
//! file; the PLY mesh reads back with an independent reader (ply-rs-bw);
//! bad arguments are refused with exit code 1 or 2.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // a test, bench or example fails loudly

use std::process::Command;

use glam::Vec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::DefaultElement;
use surfel_slam::mesh::write_surfel_ply;
use surfel_slam::SurfelMap;

fn sphere(centre: Vec3, radius: f32, n: usize) -> SurfelMap {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let mut map = SurfelMap::default();
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - y * y).sqrt();
        let t = golden * i as f32;
        let dir = Vec3::new(r * t.cos(), y, r * t.sin());
        map.push(
            centre + radius * dir,
            dir,
            [200, 80, 40, 255],
            0.004,
            12.0,
            0,
        );
    }
    map
}

fn mesh(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_surfel-slam"))
        .arg("mesh")
        .args(args)
        .output()
        .expect("runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_saved_map_becomes_mesh_files() {
    let dir = std::env::temp_dir().join(format!("surfel-slam-mesh-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let map_path = dir.join("map.ply");
    std::fs::write(
        &map_path,
        write_surfel_ply(&sphere(Vec3::new(0.0, 0.0, 1.0), 0.2, 30_000)),
    )
    .expect("write map");
    let map = map_path.to_str().expect("utf8 path");
    let ply_path = dir.join("mesh.ply");
    let (code, stdout, stderr) = mesh(&[map, "-o", ply_path.to_str().expect("utf8")]);
    assert_eq!(code, 0, "{stderr}");
    let bytes = std::fs::read(&ply_path).expect("mesh written");
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut bytes.as_slice())
        .expect("valid PLY");
    let (vertices, faces) = (ply.payload["vertex"].len(), ply.payload["face"].len());
    assert!(faces > 5000, "{faces} faces");
    assert!(
        stdout.contains(&format!(
            "{vertices} vertices, {faces} triangles from 30000 surfels"
        )),
        "{stdout}"
    );
    for name in ["mesh.glb", "mesh.obj"] {
        let path = dir.join(name);
        let (code, _, stderr) = mesh(&[
            map,
            "-o",
            path.to_str().expect("utf8"),
            "--voxel-size",
            "0.02",
        ]);
        assert_eq!(code, 0, "{stderr}");
        assert!(std::fs::metadata(&path).expect("written").len() > 10_000);
    }
    let (code, _, stderr) = mesh(&[map, "-o", "x.stl"]);
    assert_eq!(code, 2, "a bad output name is a command-line error");
    assert!(
        stderr.contains("must end in .glb, .ply or .obj"),
        "{stderr}"
    );
    let (code, _, stderr) = mesh(&[map, "-o", "x.glb", "--voxel-size=-1"]);
    assert_eq!(code, 2, "a bad voxel size is a command-line error");
    assert!(stderr.contains("voxel size"), "{stderr}");
    let (code, _, stderr) = mesh(&[
        dir.join("missing.ply").to_str().expect("utf8"),
        "-o",
        "x.glb",
    ]);
    assert_eq!(code, 1);
    assert!(stderr.contains("missing.ply"), "{stderr}");
    std::fs::write(dir.join("bad.ply"), b"ply\nformat ascii 1.0\nend_header\n").expect("write");
    let (code, _, stderr) = mesh(&[dir.join("bad.ply").to_str().expect("utf8"), "-o", "x.glb"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("bad.ply") && stderr.contains("ascii"),
        "{stderr}"
    );
    let (code, _, _) = mesh(&[map]);
    assert_eq!(code, 2, "missing -o is a command-line error");
    let _ = std::fs::remove_dir_all(&dir);
}
