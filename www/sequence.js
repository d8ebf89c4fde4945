// Sequence input: the folder picker, drag-and-drop of a folder, the bundled
// sample, and lazy per-frame file reading.
//
// A sequence is handed around as `{ name, entries }`, `entries` an array of
// `[relativePath, File | url]` ('/'-separated paths, relative to the chosen
// folder's parent, as `webkitRelativePath` spells them). The dataset layout is
// *not* parsed here: the worker passes the paths to the wasm module's
// detectLayout / parseSequence (the same parser as the native CLI).
//
// SequenceSource (DOM-free) is also used inside the worker, which reads each
// frame's files only when it needs them (File.arrayBuffer() or a same-origin
// fetch for the bundled sample).

/** Lazily readable set of files keyed by relative path. */
export class SequenceSource {
  /** @param {Array<[string, Blob|string]>} entries */
  constructor(entries) {
    this.map = new Map(entries);
  }

  get paths() {
    return [...this.map.keys()];
  }

  /** Bytes of one file (read now, not before). */
  async read(path) {
    const entry = this.map.get(path);
    if (entry === undefined) throw new Error(`${path} is missing from the folder`);
    if (typeof entry === 'string') {
      const response = await fetch(entry);
      if (!response.ok) throw new Error(`${path}: HTTP ${response.status} ${response.statusText}`);
      return response.arrayBuffer();
    }
    try {
      return await entry.arrayBuffer();
    } catch (e) {
      throw new Error(`${path}: cannot read the file (${e.message})`);
    }
  }

  async readText(path) {
    return new TextDecoder().decode(await this.read(path));
  }
}

const isHidden = (path) => path.split('/').some((c) => c.startsWith('.') && c !== '.' && c !== '..');

function folderName(paths, fallback) {
  const first = paths.find((p) => p.includes('/'));
  return first ? first.split('/')[0] : fallback;
}

/** From an `<input type=file webkitdirectory>` FileList. */
export function fromFileList(fileList) {
  const entries = [];
  for (const file of fileList) {
    const path = file.webkitRelativePath || file.name;
    if (!isHidden(path)) entries.push([path, file]);
  }
  return { name: folderName(entries.map((e) => e[0]), 'folder'), entries };
}

function readAllEntries(reader) {
  // readEntries returns at most ~100 entries per call: call until empty.
  return new Promise((resolve, reject) => {
    const all = [];
    const next = () =>
      reader.readEntries((batch) => {
        if (batch.length === 0) resolve(all);
        else {
          all.push(...batch);
          next();
        }
      }, reject);
    next();
  });
}

async function walk(entry, out) {
  if (entry.isFile) {
    const file = await new Promise((resolve, reject) => entry.file(resolve, reject));
    out.push([entry.fullPath.replace(/^\/+/, ''), file]);
  } else if (entry.isDirectory) {
    const children = await readAllEntries(entry.createReader());
    await Promise.all(children.map((c) => walk(c, out)));
  }
}

/** From a drop event's DataTransfer (a dropped folder, or several files). */
export async function fromDataTransfer(dataTransfer) {
  // webkitGetAsEntry must be called synchronously, before any await.
  const roots = [...dataTransfer.items]
    .filter((item) => item.kind === 'file')
    .map((item) => item.webkitGetAsEntry?.())
    .filter(Boolean);
  const entries = [];
  if (roots.length) {
    await Promise.all(roots.map((r) => walk(r, entries)));
  } else {
    for (const file of dataTransfer.files) entries.push([file.name, file]);
  }
  const visible = entries.filter(([p]) => !isHidden(p));
  visible.sort((a, b) => (a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : 0));
  return { name: folderName(visible.map((e) => e[0]), 'dropped files'), entries: visible };
}

/** The bundled sample: a manifest of same-origin files, fetched lazily. */
export async function fromManifest(manifestUrl) {
  const response = await fetch(manifestUrl);
  if (!response.ok) throw new Error(`cannot load ${manifestUrl}: HTTP ${response.status}`);
  const manifest = await response.json();
  const base = new URL('.', new URL(manifestUrl, location.href));
  const entries = manifest.files.map((f) => {
    const path = typeof f === 'string' ? f : f.path;
    return [path, new URL(path.split('/').map(encodeURIComponent).join('/'), base).href];
  });
  return { name: manifest.name, entries, credit: manifest.credit, licence: manifest.licence };
}

/**
 * Wires the folder input and drag-and-drop onto `dropTarget`.
 * `onSequence({name, entries})` is called for each chosen folder;
 * `onError(message)` when nothing usable was chosen.
 */
export function setupSequenceInput({ input, dropTarget, onSequence, onError }) {
  input.addEventListener('change', () => {
    if (!input.files || input.files.length === 0) {
      onError('the chosen folder is empty: no files to read');
      return;
    }
    const seq = fromFileList(input.files);
    input.value = '';
    if (seq.entries.length === 0) onError('the chosen folder holds no visible file');
    else onSequence(seq);
  });
  let depth = 0;
  const setHover = (on) => dropTarget.classList.toggle('drop-hover', on);
  dropTarget.addEventListener('dragenter', (e) => {
    e.preventDefault();
    depth++;
    setHover(true);
  });
  dropTarget.addEventListener('dragover', (e) => {
    e.preventDefault();
    e.dataTransfer.dropEffect = 'copy';
  });
  dropTarget.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) setHover(false);
  });
  dropTarget.addEventListener('drop', async (e) => {
    e.preventDefault();
    depth = 0;
    setHover(false);
    try {
      const seq = await fromDataTransfer(e.dataTransfer);
      if (seq.entries.length === 0) onError('nothing to read in what was dropped (drop a dataset folder)');
      else onSequence(seq);
    } catch (err) {
      onError(`cannot read the dropped folder: ${err.message}`);
    }
  });
}
