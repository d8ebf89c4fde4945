//! The header of the binary PLY files written here: the surfel map
//! ([`super::surfel_ply`]), the triangle mesh ([`super::export`]) and a
//! session's surfels (`crate::session`).

/// The header of a `binary_little_endian 1.0` PLY file whose `vertex`
/// element has `x y z nx ny nz` (float, world frame, metres; unit normal)
/// and `red green blue` (uchar), then the properties `extra` (`(type,
/// name)`, e.g. `("float", "radius")`); with `faces`, a `face` element of
/// that many `uchar int` index lists.
pub(crate) fn write_ply_header(
    comment: &str,
    vertices: usize,
    extra: &[(&str, &str)],
    faces: Option<usize>,
) -> String {
    let mut header = format!(
        "ply\n\
         format binary_little_endian 1.0\n\
         comment {comment}\n\
         element vertex {vertices}\n\
         property float x\n\
         property float y\n\
         property float z\n\
         property float nx\n\
         property float ny\n\
         property float nz\n\
         property uchar red\n\
         property uchar green\n\
         property uchar blue\n"
    );
    for (kind, name) in extra {
        header.push_str(&format!("property {kind} {name}\n"));
    }
    if let Some(faces) = faces {
        header.push_str(&format!(
            "element face {faces}\nproperty list uchar int vertex_indices\n"
        ));
    }
    header.push_str("end_header\n");
    header
}
