// Worker started by worker.js: reads frames' files and decodes their colour
// images with the browser, on a thread of its own. The SLAM worker's thread
// is inside wasm most of the time; every step of a read or a decode
// (fetch, arrayBuffer, createImageBitmap, getImageData) would otherwise wait
// for it between frames. Here they run while wasm works, and each frame
// reaches the SLAM worker as one message, its buffers transferred.
//
// Messages in:  {type: 'source', id, entries} (a sequence's files, as for
//               SequenceSource), {type: 'read', id, index, colour, depth,
//               decode} (relative paths; decode: false = read only).
// Messages out: {id, index, colourBuf, depthBuf, decoded} (`decoded`:
//               {width, height, rgba, preview} or null when wasm is to decode
//               the colour image; `preview` the page's thumbnail, an
//               ImageBitmap) or {id, index, error} (a file cannot be read).
import { SequenceSource } from './sequence.js';
import { readAndDecodeColour } from './colour-decode.js';

const sources = new Map(); // sequence id -> SequenceSource (the current one only)

self.onmessage = async ({ data }) => {
  if (data.type === 'source') {
    sources.clear();
    sources.set(data.id, new SequenceSource(data.entries));
    return;
  }
  if (data.type !== 'read') return;
  const { id, index } = data;
  const source = sources.get(id);
  if (!source) return; // a sequence replaced since: nobody waits for it
  try {
    const frame = await readAndDecodeColour(source, data, data.decode !== false);
    const transfer = [frame.colourBuf, frame.depthBuf];
    if (frame.decoded) transfer.push(frame.decoded.rgba.buffer);
    if (frame.decoded?.preview) transfer.push(frame.decoded.preview);
    self.postMessage({ id, index, ...frame }, transfer);
  } catch (e) {
    self.postMessage({ id, index, error: e && e.message ? e.message : String(e) });
  }
};
