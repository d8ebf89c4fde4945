// Loading the wasm module into the SLAM worker, and telling a failure of the
// module (a trap: a panic in Rust) from an error about the input. Used by
// worker.js and worker-exports.js.

export const errorText = (e) => (e && e.message ? e.message : String(e));

/**
 * Whether an exception thrown by a call into the module means the module
 * (not the input) failed: a trap (a Rust panic aborts as `unreachable`), or
 * wasm-bindgen's guards on an object a trap left borrowed or freed.
 */
export function isModuleFailure(e) {
  if (typeof WebAssembly !== 'undefined' && e instanceof WebAssembly.RuntimeError) return true;
  return /recursive use of an object|null pointer passed to rust|attempted to take ownership|unreachable|memory access out of bounds/i.test(
    errorText(e),
  );
}

/**
 * Imports and instantiates the module. Each `instance` makes a new one (the
 * URL differs, so the import is a new module record): a module that trapped
 * may be left with its stack pointer or a lock wherever the trap hit.
 */
async function importModule(path, instance) {
  const url = new URL(path, import.meta.url);
  if (instance > 0) url.searchParams.set('instance', String(instance));
  const m = await import(url.href);
  await m.default({ module_or_path: new URL(path.replace(/\.js$/, '_bg.wasm'), import.meta.url) });
  return m;
}

/**
 * The threaded module when the page is cross-origin isolated (and the URL
 * does not say threads=0), else the single-threaded SIMD one. Returns
 * `{wasm, kind: 'threads'|'simd', threads}`; why the threaded one was not
 * used goes into `notes`.
 */
export async function startModule(instance, notes) {
  const forceSingle = new URL(self.location.href).searchParams.get('threads') === '0';
  if (forceSingle) {
    notes.push('threads=0 in the page URL: using the single-threaded SIMD module');
  } else if (self.crossOriginIsolated) {
    try {
      const m = await importModule('./pkg/threads/surfel_slam.js', instance);
      const want = Math.max(1, navigator.hardwareConcurrency || 1);
      await m.initThreadPool(want);
      return { wasm: m, kind: 'threads', threads: typeof m.threadCount === 'function' ? m.threadCount() : want };
    } catch (e) {
      notes.push(`threaded module unavailable (${errorText(e)}); using the single-threaded SIMD module`);
    }
  } else {
    notes.push('page is not cross-origin isolated: using the single-threaded SIMD module');
  }
  const m = await importModule('./pkg/surfel_slam.js', instance);
  return { wasm: m, kind: 'simd', threads: typeof m.threadCount === 'function' ? m.threadCount() : 1 };
}

/** Deep copy into plain JS values (wasm-bindgen may hand out Maps or class objects). */
export function toPlain(v) {
  if (v instanceof Map) return Object.fromEntries([...v].map(([k, x]) => [k, toPlain(x)]));
  if (Array.isArray(v)) return v.map(toPlain);
  if (ArrayBuffer.isView(v)) return v.slice();
  if (v && typeof v === 'object') {
    const o = {};
    for (const k of Object.keys(v)) o[k] = toPlain(v[k]);
    return o;
  }
  return v;
}
