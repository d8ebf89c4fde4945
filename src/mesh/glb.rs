//! glTF 2.0 binary (`.glb`) files: a triangle mesh, or the surfel cloud as
//! points, each with normals and vertex colours (`COLOR_0`, RGBA8). The
//! JSON is built with `gltf-json`; this file only frames it with the binary
//! buffer (GLB header and chunks).
//!
//! glTF's +y is up, while the map's world frame is the first camera's (+y
//! down, +z forward): the data stay in the world frame and the node turns
//! them half a turn about x, so viewers show the scene upright as the first
//! camera saw it.

use std::collections::BTreeMap;

use glam::Vec3;
use gltf_json as json;
use json::validation::{Checked, USize64};

use super::TriangleMesh;
use crate::fusion::SurfelMap;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The parts of one primitive, borrowed.
struct Primitive<'a> {
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    colours: &'a [[u8; 4]],
    triangles: Option<&'a [[u32; 3]]>,
}

/// The mesh as a `.glb` (triangles, normals, vertex colours). An empty mesh
/// gives a valid file with an empty scene.
#[must_use]
pub fn write_glb_mesh(mesh: &TriangleMesh) -> Vec<u8> {
    let n = mesh
        .positions
        .len()
        .min(mesh.normals.len())
        .min(mesh.colours.len());
    write_glb(&Primitive {
        positions: &mesh.positions[..n],
        normals: &mesh.normals[..n],
        colours: &mesh.colours[..n],
        triangles: Some(&mesh.triangles),
    })
}

/// The surfels at least `min_confidence` confident (and with finite values
/// and a unit normal) as a `.glb` point cloud with normals and colours.
#[must_use]
pub fn write_glb_points(map: &SurfelMap, min_confidence: f32) -> Vec<u8> {
    let n = map
        .positions()
        .len()
        .min(map.normals().len())
        .min(map.colours().len())
        .min(map.confidences().len());
    let (mut positions, mut normals, mut colours) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let (p, c) = (map.positions()[i], map.confidences()[i]);
        let Some(normal) = map.normals()[i].try_normalize() else {
            continue;
        };
        if c >= min_confidence && p.is_finite() {
            positions.push(p);
            normals.push(normal);
            colours.push(map.colours()[i]);
        }
    }
    write_glb(&Primitive {
        positions: &positions,
        normals: &normals,
        colours: &colours,
        triangles: None,
    })
}

fn view(
    root: &mut json::Root,
    offset: usize,
    length: usize,
    target: json::buffer::Target,
) -> json::Index<json::buffer::View> {
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(length),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        target: Some(Checked::Valid(target)),
        extensions: None,
        extras: Default::default(),
    })
}

fn accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    normalized: bool,
    bounds: Option<(Vec3, Vec3)>,
) -> json::Index<json::Accessor> {
    let to_json = |v: Vec3| json::Value::from(vec![v.x, v.y, v.z]);
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(type_),
        min: bounds.map(|b| to_json(b.0)),
        max: bounds.map(|b| to_json(b.1)),
        normalized,
        sparse: None,
    })
}

fn write_glb(prim: &Primitive) -> Vec<u8> {
    let count = prim.positions.len();
    let triangles = prim.triangles.unwrap_or(&[]);
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("surfel-slam {}", env!("CARGO_PKG_VERSION"))),
            version: "2.0".to_owned(),
            copyright: None,
            extensions: None,
            extras: Default::default(),
            min_version: None,
        },
        ..Default::default()
    };
    let mut bin = Vec::new();
    // A glTF accessor needs at least one element: an empty mesh or cloud
    // is a file without buffers or meshes.
    let drawable = count > 0 && (prim.triangles.is_none() || !triangles.is_empty());
    if drawable {
        let accessors = push_buffers(&mut root, prim, &mut bin);
        push_scene(&mut root, prim, accessors);
    }
    // Serialising these plain structs cannot fail; an empty object would
    // still frame into a file the validator reports.
    let mut text = root.to_vec().unwrap_or_else(|_| b"{}".to_vec());
    glb_frame(&mut text, bin)
}

/// The accessors of one primitive's attributes (and indices, for a mesh).
struct Accessors {
    position: json::Index<json::Accessor>,
    normal: json::Index<json::Accessor>,
    colour: json::Index<json::Accessor>,
    indices: Option<json::Index<json::Accessor>>,
}

/// Appends the primitive's attributes (and triangle indices) to `bin` and
/// describes them in `root`: one buffer, its views, their accessors.
fn push_buffers(root: &mut json::Root, prim: &Primitive, bin: &mut Vec<u8>) -> Accessors {
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;

    let count = prim.positions.len();
    let triangles = prim.triangles.unwrap_or(&[]);
    let (lo, hi) = prim.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let mut push_view = |bytes: &mut Vec<u8>, target| {
        let start = bin.len();
        bin.append(bytes);
        (start, bin.len() - start, target)
    };
    let mut position_bytes: Vec<u8> = prim
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let mut normal_bytes: Vec<u8> = prim
        .normals
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let mut colour_bytes: Vec<u8> = prim.colours.iter().flatten().copied().collect();
    let mut index_bytes: Vec<u8> = triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let views = [
        push_view(&mut position_bytes, Target::ArrayBuffer),
        push_view(&mut normal_bytes, Target::ArrayBuffer),
        push_view(&mut colour_bytes, Target::ArrayBuffer),
        push_view(&mut index_bytes, Target::ElementArrayBuffer),
    ];
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let [pv, nv, cv, iv] = views;
    let pv = view(root, pv.0, pv.1, pv.2);
    let nv = view(root, nv.0, nv.1, nv.2);
    let cv = view(root, cv.0, cv.1, cv.2);
    let position = accessor(
        root,
        pv,
        count,
        ComponentType::F32,
        Type::Vec3,
        false,
        Some((lo, hi)),
    );
    let normal = accessor(root, nv, count, ComponentType::F32, Type::Vec3, false, None);
    let colour = accessor(root, cv, count, ComponentType::U8, Type::Vec4, true, None);
    let indices = if prim.triangles.is_some() {
        let iv = view(root, iv.0, iv.1, iv.2);
        Some(accessor(
            root,
            iv,
            triangles.len() * 3,
            ComponentType::U32,
            Type::Scalar,
            false,
            None,
        ))
    } else {
        None
    };
    Accessors {
        position,
        normal,
        colour,
        indices,
    }
}

/// The material, mesh, node and scene of the primitive in `root`.
fn push_scene(root: &mut json::Root, prim: &Primitive, accessors: Accessors) {
    let Accessors {
        position,
        normal,
        colour,
        indices,
    } = accessors;
    let material = root.push(json::Material {
        double_sided: true,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        ..Default::default()
    });
    let mut attributes = BTreeMap::new();
    attributes.insert(Checked::Valid(json::mesh::Semantic::Positions), position);
    attributes.insert(Checked::Valid(json::mesh::Semantic::Normals), normal);
    attributes.insert(Checked::Valid(json::mesh::Semantic::Colors(0)), colour);
    let mode = if prim.triangles.is_some() {
        json::mesh::Mode::Triangles
    } else {
        json::mesh::Mode::Points
    };
    let mesh = root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices,
            material: Some(material),
            mode: Checked::Valid(mode),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh),
        // Half a turn about x: world +y down becomes glTF +y up.
        rotation: Some(json::scene::UnitQuaternion([1.0, 0.0, 0.0, 0.0])),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        nodes: vec![node],
    });
    root.scene = Some(scene);
}

/// Frames the JSON and the binary buffer as a GLB file.
fn glb_frame(text: &mut Vec<u8>, mut bin: Vec<u8>) -> Vec<u8> {
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    // glTF files are limited to 4 GiB; the block budget keeps meshes far below.
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
}
