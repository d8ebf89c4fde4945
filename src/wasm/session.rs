//! `Slam.save()` and `Slam.load(bytes, options)`'s JS side: the load
//! options object and session errors as JS errors. The session format and
//! its checks are the library's (`crate::session`).

use js_sys::Reflect;
use wasm_bindgen::prelude::*;

use super::convert::InputError;
use crate::session::SessionError;

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r#"
/** Options of `Slam.load(bytes, options)`. */
export interface LoadOptions {
  /** Place the next frames in the loaded map without changing it (no fusion, no loop closure, no new keyframes); the first frame is placed by relocalisation against the session's keyframes, a frame that cannot be placed is reported 'unplaced'. Default false: mapping continues exactly where the session stopped. */
  localise?: boolean;
}
"#;

/// The option keys `load` reads.
const KEYS: [&str; 1] = ["localise"];

/// What `Slam.load` was asked for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Localise in the loaded map instead of mapping on.
    pub localise: bool,
}

impl LoadOptions {
    /// Reads `{ localise?: boolean }`, or `undefined` / `null` for the
    /// defaults; refuses another type, an unknown key (naming the known
    /// ones) or a `localise` that is not a boolean.
    pub fn from_js(value: &JsValue) -> Result<Self, InputError> {
        if value.is_undefined() || value.is_null() {
            return Ok(Self::default());
        }
        if !value.is_object() {
            return Err(InputError(
                "load options must be an object like { localise: true }".into(),
            ));
        }
        let object: &js_sys::Object = value.unchecked_ref();
        for key in js_sys::Object::keys(object).iter() {
            let key = key.as_string().unwrap_or_default();
            if !KEYS.contains(&key.as_str()) {
                return Err(InputError(format!(
                    "unknown load option {key:?}; known options: {}",
                    KEYS.join(", ")
                )));
            }
        }
        let localise =
            Reflect::get(value, &JsValue::from_str("localise")).unwrap_or(JsValue::UNDEFINED);
        let localise = match (localise.is_undefined(), localise.as_bool()) {
            (true, _) => false,
            (false, Some(b)) => b,
            (false, None) => {
                return Err(InputError(
                    "load options: localise must be a boolean".into(),
                ))
            }
        };
        Ok(Self { localise })
    }
}

/// A session error as a JS `Error` whose message starts with its kind
/// (`truncated: ...`, `corrupt: ...`, see [`SessionError::kind`]).
#[must_use]
pub fn session_error(e: &SessionError) -> JsError {
    JsError::new(&format!("{}: {e}", e.kind()))
}
