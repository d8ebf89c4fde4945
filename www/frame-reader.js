// Worker started by worker.js: reads frames' files and decodes their colour
// images with the browser, on a thread of its own. The SLAM worker's thread
// is inside wasm most of the time; every step of a read or a decode
// (fetch, arrayBuffer, createImageBitmap, getImageData) would otherwise wait
// for it between frames. Here they run while wasm works, and each frame
// reaches the SLAM worker as one message, its buffers transferred.
//
// Files are read ahead in batches ('readAhead'), not one frame at a time:
// each read wakes several browser threads (network or blob IPC), and while
// they run they take the cores from the wasm threads. A batch every
// READ_BATCH frames leaves the frames in between undisturbed.
//
// Messages: ToReader in protocol.js. Out: {id, index, colourBuf, depthBuf,
// decoded} (`decoded`: {width, height, rgba, preview} or null when wasm is to
// decode the colour image; `preview` the page's thumbnail, an ImageBitmap) or
// {id, index, error} (a file cannot be read). A source's entries are a
// folder's files or one archive (see openSource in sequence.js).
import { ToReader } from './protocol.js';
import { openSource } from './sequence.js';
import { readAndDecodeColour } from './colour-decode.js';

// sequence id -> promise of its SequenceSource / ArchiveSource (the current one only)
const sources = new Map();

// An archive is read through the wasm module's ArchiveReader: this worker
// loads the single-threaded module for it, once, only when one is opened.
let wasmModule = null;
const loadWasm = () =>
  (wasmModule ??= import('./pkg/surfel_slam.js').then(async (m) => {
    await m.default();
    return m;
  }));
// path -> promise of its bytes, read ahead for the current sequence; an entry
// is taken (deleted) by the 'read' that uses it.
const ahead = new Map();

/** A SequenceSource-like reader that uses (and drops) the bytes read ahead. */
const cachedReader = (source) => ({
  read(path) {
    const bytes = ahead.get(path);
    if (!bytes) return source.read(path);
    ahead.delete(path);
    return bytes;
  },
});

self.onmessage = async ({ data }) => {
  if (data.type === ToReader.SOURCE) {
    sources.clear();
    ahead.clear();
    const opening = openSource(data.entries, loadWasm);
    opening.catch(() => {}); // reported by each 'read' that needs it
    sources.set(data.id, opening);
    return;
  }
  const opening = sources.get(data.id);
  if (!opening) return; // a sequence replaced since: nobody waits for it
  let source;
  try {
    source = await opening;
  } catch (e) {
    if (data.type === ToReader.READ) self.postMessage({ id: data.id, index: data.index, error: e && e.message ? e.message : String(e) });
    return;
  }
  if (sources.get(data.id) !== opening) return;
  if (data.type === ToReader.READ_AHEAD) {
    for (const path of data.paths) {
      if (ahead.has(path)) continue;
      const bytes = source.read(path);
      bytes.catch(() => {}); // reported by the 'read' that takes it
      ahead.set(path, bytes);
    }
    return;
  }
  if (data.type !== ToReader.READ) return;
  const { id, index } = data;
  try {
    const frame = await readAndDecodeColour(cachedReader(source), data, data.decode !== false);
    const transfer = [frame.colourBuf, frame.depthBuf, frame.confidenceBuf].filter(Boolean);
    if (frame.decoded) transfer.push(frame.decoded.rgba.buffer);
    if (frame.decoded?.preview) transfer.push(frame.decoded.preview);
    self.postMessage({ id, index, ...frame }, transfer);
  } catch (e) {
    self.postMessage({ id, index, error: e && e.message ? e.message : String(e) });
  }
};
