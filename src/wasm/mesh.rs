//! Meshes and 3D files from JavaScript: `slam.exportMesh(options, progress)`,
//! `slam.exportGlbPoints(minConfidence)` and `meshSurfelPly(bytes, options,
//! progress)`. A thin shell over [`crate::mesh`].
//!
//! `options` is `{ format: 'glb' | 'ply' | 'obj', voxelSize (m), minConfidence }`,
//! every field optional (defaults: 'glb', 0.01 m, the map's stable
//! confidence); unknown fields are an error (usually typos). `progress`, if
//! given, is called with the fraction done (0..1) a few dozen times, on the
//! calling thread (the page calls this in its worker).

use std::cell::RefCell;

use js_sys::{Function, Object, Reflect};
use wasm_bindgen::prelude::*;

use super::slam::Slam;
use crate::fusion::SurfelMap;
use crate::mesh::{
    read_surfel_ply, write_glb_points, write_mesh, MeshConfig, MeshFormat, Mesher, TriangleMesh,
};

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r#"
/** Options of `exportMesh` and `meshSurfelPly`. */
export interface MeshOptions {
  /** File format of the returned bytes (default 'glb'). */
  format?: 'glb' | 'ply' | 'obj';
  /** Voxel edge, metres (default 0.01). */
  voxelSize?: number;
  /** Use only surfels at least this confident (default: the stable confidence). */
  minConfidence?: number;
}
"#;

thread_local! {
    /// The mesher and the mesh, kept between calls so that repeated exports
    /// reuse their buffers.
    static MESHER: RefCell<(Mesher, TriangleMesh)> = RefCell::new((Mesher::new(), TriangleMesh::default()));
}

/// The options object: format and config (with `min_confidence` defaulting to `stable`).
fn parse_options(options: &JsValue, stable: f32) -> Result<(MeshFormat, MeshConfig), JsError> {
    let mut format = MeshFormat::Glb;
    let mut config = MeshConfig {
        min_confidence: stable,
        ..MeshConfig::default()
    };
    if options.is_undefined() || options.is_null() {
        return Ok((format, config));
    }
    if !options.is_object() {
        return Err(JsError::new("mesh options must be an object"));
    }
    let number = |key: &str, value: &JsValue| {
        value
            .as_f64()
            .filter(|v| v.is_finite())
            .map(|v| v as f32)
            .ok_or_else(|| JsError::new(&format!("mesh option {key} must be a finite number")))
    };
    for key in Object::keys(options.unchecked_ref::<Object>()).iter() {
        let name = key.as_string().unwrap_or_default();
        let value = Reflect::get(options, &key).unwrap_or(JsValue::UNDEFINED);
        if value.is_undefined() {
            continue;
        }
        match name.as_str() {
            "format" => {
                format = value
                    .as_string()
                    .and_then(|s| MeshFormat::from_name(&s))
                    .ok_or_else(|| {
                        JsError::new("mesh option format must be 'glb', 'ply' or 'obj'")
                    })?;
            }
            "voxelSize" => config.voxel_size_m = number("voxelSize", &value)?,
            "minConfidence" => config.min_confidence = number("minConfidence", &value)?,
            _ => {
                return Err(JsError::new(&format!(
                    "unknown mesh option {name:?} (known: format, voxelSize, minConfidence)"
                )))
            }
        }
    }
    config.validate()?;
    Ok((format, config))
}

/// Meshes `map` and returns the file bytes; `progress` gets fractions.
fn mesh_to_bytes(
    map: &SurfelMap,
    format: MeshFormat,
    config: &MeshConfig,
    progress: Option<&Function>,
) -> Result<Vec<u8>, JsError> {
    MESHER.with(|cell| {
        let mut guard = cell.try_borrow_mut().map_err(|_| {
            JsError::new(
                "a mesh export is already running (called from its own progress callback?)",
            )
        })?;
        let (mesher, mesh) = &mut *guard;
        // A throwing progress callback must not abort the meshing half way;
        // its error is dropped.
        let mut report = |f: f32| {
            if let Some(p) = progress {
                let _ = p.call1(&JsValue::NULL, &JsValue::from_f64(f64::from(f)));
            }
        };
        mesher.mesh_into(map, config, mesh, &mut report)?;
        Ok(write_mesh(mesh, format))
    })
}

/// The options object as a JS value (`undefined` when omitted or null).
fn options_value(options: Option<Object>) -> JsValue {
    options.map_or(JsValue::UNDEFINED, JsValue::from)
}

#[wasm_bindgen]
impl Slam {
    /// The map as a triangle mesh file (`options`: see [`MeshOptions`];
    /// `progress(fraction)` optional). World frame of the map (the first
    /// camera's), metres; the `.glb` turns it upright for glTF's +y up.
    #[wasm_bindgen(js_name = exportMesh)]
    pub fn export_mesh(
        &self,
        #[wasm_bindgen(unchecked_optional_param_type = "MeshOptions")] options: Option<Object>,
        #[wasm_bindgen(unchecked_optional_param_type = "(fraction: number) => void")]
        progress: Option<Function>,
    ) -> Result<Vec<u8>, JsError> {
        let stable = self.pipeline().config().fusion.stable_confidence;
        let (format, config) = parse_options(&options_value(options), stable)?;
        mesh_to_bytes(self.pipeline().map(), format, &config, progress.as_ref())
    }

    /// The surfels at least `minConfidence` confident (default: the stable
    /// confidence) as a `.glb` point cloud with normals and colours.
    #[wasm_bindgen(js_name = exportGlbPoints)]
    pub fn export_glb_points(&self, min_confidence: Option<f64>) -> Result<Vec<u8>, JsError> {
        let stable = self.pipeline().config().fusion.stable_confidence;
        let c = match min_confidence {
            None => stable,
            Some(c) if c.is_finite() => c as f32,
            Some(c) => {
                return Err(JsError::new(&format!(
                    "minConfidence must be a finite number, got {c}"
                )))
            }
        };
        Ok(write_glb_points(self.pipeline().map(), c))
    }
}

/// Meshes a saved surfel map (binary PLY as `exportPly` writes it, or a
/// point cloud with normals) and returns the mesh file bytes.
#[wasm_bindgen(js_name = meshSurfelPly)]
pub fn mesh_surfel_ply(
    ply: &[u8],
    #[wasm_bindgen(unchecked_optional_param_type = "MeshOptions")] options: Option<Object>,
    #[wasm_bindgen(unchecked_optional_param_type = "(fraction: number) => void")] progress: Option<
        Function,
    >,
) -> Result<Vec<u8>, JsError> {
    let map = read_surfel_ply(ply)?;
    let stable = crate::fusion::FusionConfig::default().stable_confidence;
    let (format, config) = parse_options(&options_value(options), stable)?;
    mesh_to_bytes(&map, format, &config, progress.as_ref())
}
