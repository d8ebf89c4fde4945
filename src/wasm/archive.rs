//! `ArchiveReader`: a dataset packed in a `.zip`, `.tar` or `.tar.gz` for
//! JavaScript, through the same reader as the native CLI
//! ([`crate::dataset::ArchiveReader`]). The archive's bytes come either all
//! at once (a `Uint8Array`) or on demand from a callback, so that a page can
//! read a picked `File` piece by piece (`FileReaderSync` on `file.slice`, in
//! a worker) without loading it whole.

use std::io::{self, Read, Seek, SeekFrom};

use js_sys::{Array, Function, Reflect, Uint8Array};
use wasm_bindgen::prelude::*;

use crate::dataset::{ArchiveFormat, ArchiveReader as Reader};

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r#"
/** Bytes of an archive read on demand: `read(offset, length)` returns those bytes (fewer only at the end). */
export interface ArchiveSource {
  /** Size of the archive, bytes. */
  size: number;
  read(offset: number, length: number): Uint8Array | ArrayBuffer;
}
"#;

/// The archive's bytes: in wasm memory, or read through a JS callback.
enum Bytes {
    Memory(io::Cursor<Vec<u8>>),
    Callback {
        read: Function,
        size: u64,
        position: u64,
    },
}

impl Read for Bytes {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Self::Memory(cursor) => cursor.read(buf),
            Self::Callback {
                read,
                size,
                position,
            } => {
                let want = (*size).saturating_sub(*position).min(buf.len() as u64);
                if want == 0 {
                    return Ok(0);
                }
                let value = read
                    .call2(
                        &JsValue::NULL,
                        &JsValue::from_f64(*position as f64),
                        &JsValue::from_f64(want as f64),
                    )
                    .map_err(|e| io::Error::other(js_message(&e)))?;
                if !(value.is_instance_of::<Uint8Array>()
                    || value.is_instance_of::<js_sys::ArrayBuffer>())
                {
                    return Err(io::Error::other(
                        "the archive source's read() must return a Uint8Array or an ArrayBuffer",
                    ));
                }
                let bytes = Uint8Array::new(&value);
                let n = (bytes.length() as usize).min(want as usize);
                if n == 0 {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "the archive source returned no bytes before its stated size",
                    ));
                }
                bytes.subarray(0, n as u32).copy_to(&mut buf[..n]);
                *position += n as u64;
                Ok(n)
            }
        }
    }
}

impl Seek for Bytes {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        match self {
            Self::Memory(cursor) => cursor.seek(to),
            Self::Callback { size, position, .. } => {
                let target = match to {
                    SeekFrom::Start(n) => Some(n),
                    SeekFrom::End(d) => size.checked_add_signed(d),
                    SeekFrom::Current(d) => position.checked_add_signed(d),
                };
                *position = target.ok_or_else(|| {
                    io::Error::new(io::ErrorKind::InvalidInput, "seek before the start")
                })?;
                Ok(*position)
            }
        }
    }
}

fn js_message(e: &JsValue) -> String {
    e.dyn_ref::<js_sys::Error>()
        .map(|e| String::from(e.message()))
        .or_else(|| e.as_string())
        .unwrap_or_else(|| "the archive source's read() threw".to_owned())
}

/// A dataset archive (`.zip`, `.tar`, `.tar.gz` / `.tgz`, format sniffed from
/// its first bytes). `new ArchiveReader(source, name)`: `source` a
/// `Uint8Array` (the whole archive) or `{ size, read(offset, length) }`;
/// `name` names it in errors. `names` lists its files ('/' separated, as in
/// the archive), `read(name)` returns one file's bytes. Feed `names` and the
/// index texts to `detectLayout` / `parseSequence` as for a folder.
#[wasm_bindgen]
pub struct ArchiveReader {
    inner: Reader<Bytes>,
}

#[wasm_bindgen]
impl ArchiveReader {
    /// Opens the archive; throws an Error naming it when it is not a zip,
    /// tar or gzip archive, or is corrupt or truncated.
    #[wasm_bindgen(constructor)]
    pub fn new(
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | ArchiveSource")] source: JsValue,
        name: &str,
    ) -> Result<ArchiveReader, JsError> {
        let bytes = if let Some(array) = source.dyn_ref::<Uint8Array>() {
            Bytes::Memory(io::Cursor::new(array.to_vec()))
        } else if source.is_object() {
            let get = |key: &str| Reflect::get(&source, &JsValue::from_str(key)).ok();
            let read = get("read").and_then(|f| f.dyn_into::<Function>().ok());
            let size = get("size")
                .and_then(|s| s.as_f64())
                .filter(|s| s.is_finite() && *s >= 0.0 && *s <= 2f64.powi(53));
            match (read, size) {
                (Some(read), Some(size)) => Bytes::Callback {
                    read,
                    size: size as u64,
                    position: 0,
                },
                _ => {
                    return Err(JsError::new(&format!(
                        "{name}: the archive source must be a Uint8Array or {{ size: number, read(offset, length) }}"
                    )))
                }
            }
        } else {
            return Err(JsError::new(&format!(
                "{name}: the archive source must be a Uint8Array or {{ size: number, read(offset, length) }}"
            )));
        };
        let inner = Reader::new(bytes, name)?;
        Ok(Self { inner })
    }

    /// Every file in the archive, sorted.
    #[wasm_bindgen(getter, unchecked_return_type = "string[]")]
    #[must_use]
    pub fn names(&self) -> Array {
        self.inner
            .names()
            .iter()
            .map(|n| JsValue::from_str(n))
            .collect()
    }

    /// `'zip' | 'tar' | 'tar.gz'`.
    #[wasm_bindgen(getter)]
    #[must_use]
    pub fn format(&self) -> String {
        let format: ArchiveFormat = self.inner.format();
        format.name().to_owned()
    }

    /// The bytes of one file (a copy); throws an Error naming the archive and
    /// the file when it is absent or cannot be read.
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>, JsError> {
        Ok(self.inner.read(name)?)
    }
}
