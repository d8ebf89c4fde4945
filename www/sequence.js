// Sequence input: the folder picker, the archive picker, drag-and-drop of a
// folder or an archive, the bundled sample, and lazy per-frame file reading.
//
// A sequence is handed around as `{ name, entries }`, `entries` an array of
// `[relativePath, File | url]` ('/'-separated paths, relative to the chosen
// folder's parent, as `webkitRelativePath` spells them). An archive (.zip,
// .tar, .tar.gz / .tgz) is one entry, `[fileName, File]`. The dataset layout
// is *not* parsed here: the worker passes the paths to the wasm module's
// detectLayout / parseSequence (the same parser as the native CLI).
//
// openSource() (DOM-free) is used inside the workers, which read each frame's
// files only when they need them: File.arrayBuffer() or a same-origin fetch
// for a folder or the bundled sample; for an archive, the wasm module's
// ArchiveReader (the same reader as the CLI), which reads the File piece by
// piece with FileReaderSync (never the whole archive at once, except a
// .tar.gz, which it decompresses in order, see src/dataset/archive.rs).

/** Whether a file name is an archive the wasm ArchiveReader reads. */
export const isArchiveName = (name) => /\.(zip|tar|tgz|tar\.gz)$/i.test(name);

/** `teddy.tar.gz` -> `teddy`. */
export const archiveStem = (name) => name.replace(/\.(zip|tar|tgz|tar\.gz)$/i, '');

/** A size in bytes for people: 12 MB, 3.4 MB, 512 KB, 1.2 GB. */
export function formatBytes(bytes) {
  const mb = bytes / 2 ** 20;
  if (mb >= 1024) return `${(mb / 1024).toFixed(1)} GB`;
  if (mb >= 10) return `${mb.toFixed(0)} MB`;
  if (mb >= 1) return `${mb.toFixed(1)} MB`;
  return `${Math.max(1, Math.round(bytes / 1024))} KB`;
}

/** The sequence line while a sequence is opened: what is read (an archive by its file name and size, a folder by its file count). */
export function readingLine({ name, entries }) {
  if (entries.length === 1 && isArchiveName(entries[0][0])) {
    const file = entries[0][1];
    const size = typeof file === 'string' || !Number.isFinite(file?.size) ? '' : ` (${formatBytes(file.size)})`;
    return `reading archive ${entries[0][0].split('/').pop()}${size}…`;
  }
  return `reading ${name} (${entries.length} file${entries.length === 1 ? '' : 's'})…`;
}

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

/** The files of an archive, read through the wasm module's ArchiveReader. */
export class ArchiveSource {
  /** @param reader a wasm ArchiveReader */
  constructor(reader) {
    this.reader = reader;
    this.names = reader.names;
    this.set = new Set(this.names);
  }

  get paths() {
    return this.names;
  }

  /** Bytes of one file (an ArrayBuffer of its own, transferable). */
  async read(path) {
    if (!this.set.has(path)) throw new Error(`${path} is missing from the archive`);
    return this.reader.read(path).buffer;
  }

  async readText(path) {
    return new TextDecoder().decode(await this.read(path));
  }
}

/**
 * The files of a sequence: a SequenceSource, or an ArchiveSource when the
 * entries are one archive. `loadWasm()` returns the initialised wasm module
 * (called only for an archive).
 */
export async function openSource(entries, loadWasm) {
  if (entries.length !== 1 || !isArchiveName(entries[0][0])) return new SequenceSource(entries);
  const [name, file] = entries[0];
  const wasm = await loadWasm();
  let source;
  if (typeof file !== 'string' && typeof FileReaderSync === 'function') {
    // Pieces on demand: a worker may read a Blob synchronously, which the
    // reader (synchronous Rust io::Read) needs.
    const sync = new FileReaderSync();
    source = { size: file.size, read: (offset, length) => sync.readAsArrayBuffer(file.slice(offset, offset + length)) };
  } else {
    const bytes = typeof file === 'string' ? await (await fetch(file)).arrayBuffer() : await file.arrayBuffer();
    source = new Uint8Array(bytes);
  }
  return new ArchiveSource(new wasm.ArchiveReader(source, name));
}

const isHidden = (path) => path.split('/').some((c) => c.startsWith('.') && c !== '.' && c !== '..');

function folderName(paths, fallback) {
  const first = paths.find((p) => p.includes('/'));
  return first ? first.split('/')[0] : fallback;
}

/** A sequence that is one archive file. */
export const fromArchiveFile = (file) => ({ name: archiveStem(file.name), entries: [[file.name, file]] });

/** From an `<input type=file webkitdirectory>` FileList (or one archive picked). */
export function fromFileList(fileList) {
  if (fileList.length === 1 && isArchiveName(fileList[0].name)) return fromArchiveFile(fileList[0]);
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
  if (entries.length === 1 && isArchiveName(entries[0][0]) && typeof entries[0][1] !== 'string') {
    return fromArchiveFile(entries[0][1]);
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
 * Wires the folder input, the archive input and drag-and-drop onto
 * `dropTarget`. `onSequence({name, entries})` is called for each chosen
 * folder or archive;
 * `onError(message)` when nothing usable was chosen.
 */
export function setupSequenceInput({ input, archiveInput = null, dropTarget, onSequence, onError }) {
  archiveInput?.addEventListener('change', () => {
    const file = archiveInput.files?.[0];
    archiveInput.value = '';
    if (!file) return;
    if (isArchiveName(file.name)) onSequence(fromArchiveFile(file));
    else onError(`${file.name}: not a .zip, .tar, .tar.gz or .tgz archive`);
  });
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
