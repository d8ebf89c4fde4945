// The video track of an MP4 (ISO BMFF) file: its codec, as WebCodecs names
// it, its decoder configuration and its samples, for VideoDecoder. Used for a
// Stray Scanner scan's rgb.mp4 (HEVC from an iPhone; H.264 elsewhere).
// DOM-free: it runs in the workers and under Node.
//
// A sample's bytes are `bytes.subarray(offset, offset + size)`; samples are
// listed in decode order, with `rank` their place in presentation order (a
// stream with B-frames decodes a frame before the ones it is shown after).
// Frame i of the scan is the sample of rank i.

/** Box types whose payload is a list of boxes. */
const CONTAINERS = new Set(['moov', 'trak', 'mdia', 'minf', 'stbl', 'edts', 'dinf']);

/** Boxes an MP4 file may start with. */
const TOP_LEVEL = new Set(['ftyp', 'moov', 'mdat', 'free', 'skip', 'wide', 'uuid']);

/** Why a file is not a video this reader can list: names the box concerned. */
export class Mp4Error extends Error {}

/** The boxes in `bytes[from, to)`: `[{type, start, end}]` (`start` after the header). */
function boxes(bytes, from, to) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = [];
  let at = from;
  while (at + 8 <= to) {
    let size = view.getUint32(at);
    const type = String.fromCharCode(bytes[at + 4], bytes[at + 5], bytes[at + 6], bytes[at + 7]);
    let header = 8;
    if (size === 1) {
      if (at + 16 > to) throw new Mp4Error(`box ${type} at byte ${at}: truncated header`);
      size = Number(view.getBigUint64(at + 8));
      header = 16;
    } else if (size === 0) {
      size = to - at;
    }
    if (size < header || at + size > to) throw new Mp4Error(`box ${type} at byte ${at}: its size ${size} runs past the end (the file is truncated?)`);
    out.push({ type, start: at + header, end: at + size });
    at += size;
  }
  return out;
}

/** The first box of `type` under `parent` (`{start, end}`), following `path` ('moov/trak'...), or null. */
function find(bytes, parent, path) {
  let box = parent;
  for (const type of path.split('/')) {
    box = boxes(bytes, box.start, box.end).find((b) => b.type === type) ?? null;
    if (!box) return null;
  }
  return box;
}

/** A box's payload after its version and flags, with readers that name the box when it ends early. */
function fullBox(bytes, box, type) {
  if (!box) throw new Mp4Error(`no ${type} box in the video track`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const version = bytes[box.start];
  let at = box.start + 4;
  const need = (n) => {
    if (at + n > box.end) throw new Mp4Error(`${type}: truncated`);
  };
  return {
    version,
    u8() {
      need(1);
      return bytes[at++];
    },
    u32() {
      need(4);
      const v = view.getUint32(at);
      at += 4;
      return v;
    },
    i32() {
      need(4);
      const v = view.getInt32(at);
      at += 4;
      return v;
    },
    u64() {
      need(8);
      const v = Number(view.getBigUint64(at));
      at += 8;
      return v;
    },
    skip(n) {
      need(n);
      at += n;
    },
  };
}

const hex = (n) => n.toString(16).padStart(2, '0');

/** `avc1.PPCCLL` from an avcC payload. */
function avcCodec(type, config) {
  if (config.length < 4) throw new Mp4Error('avcC: truncated');
  return `${type}.${hex(config[1])}${hex(config[2])}${hex(config[3])}`;
}

/** `hvc1.1.6.L93.B0` from an hvcC payload (ISO/IEC 14496-15, annex E). */
function hevcCodec(type, config) {
  if (config.length < 13) throw new Mp4Error('hvcC: truncated');
  const space = ['', 'A', 'B', 'C'][config[1] >> 6];
  const tier = config[1] & 0x20 ? 'H' : 'L';
  const profile = config[1] & 0x1f;
  let flags = ((config[2] << 24) | (config[3] << 16) | (config[4] << 8) | config[5]) >>> 0;
  let reversed = 0;
  for (let i = 0; i < 32; i++) {
    reversed = ((reversed << 1) | (flags & 1)) >>> 0;
    flags >>>= 1;
  }
  const constraints = Array.from(config.subarray(6, 12));
  while (constraints.length && constraints[constraints.length - 1] === 0) constraints.pop();
  const tail = constraints.map((b) => `.${b.toString(16).toUpperCase()}`).join('');
  return `${type}.${space}${profile}.${reversed.toString(16).toUpperCase()}.${tier}${config[12]}${tail}`;
}

/** Sample entries this reader names a codec for, and the configuration box each carries. */
const SAMPLE_ENTRIES = { avc1: ['avcC', avcCodec], avc3: ['avcC', avcCodec], hvc1: ['hvcC', hevcCodec], hev1: ['hvcC', hevcCodec] };

/**
 * The first video track of MP4 `bytes` (a Uint8Array): `{codec, description,
 * width, height, timescale, samples: [{offset, size, key, time, rank}]}`
 * (`description` the avcC / hvcC payload VideoDecoder wants; `time` the
 * presentation time in `timescale` units). Throws an Mp4Error naming what
 * is missing or malformed.
 */
export function parseMp4(bytes) {
  if (!(bytes instanceof Uint8Array)) bytes = new Uint8Array(bytes);
  const file = { start: 0, end: bytes.length };
  const first = bytes.length >= 8 ? String.fromCharCode(...bytes.subarray(4, 8)) : '';
  if (!TOP_LEVEL.has(first)) throw new Mp4Error('not an MP4 file (it does not start with an ftyp, moov or mdat box)');
  const moov = find(bytes, file, 'moov');
  if (!moov) throw new Mp4Error('no moov box (the file is truncated?)');
  const track = boxes(bytes, moov.start, moov.end)
    .filter((b) => b.type === 'trak')
    .find((trak) => {
      const hdlr = find(bytes, trak, 'mdia/hdlr');
      return hdlr && hdlr.start + 12 <= hdlr.end && String.fromCharCode(...bytes.subarray(hdlr.start + 8, hdlr.start + 12)) === 'vide';
    });
  if (!track) throw new Mp4Error('no video track');
  const mdhd = fullBox(bytes, find(bytes, track, 'mdia/mdhd'), 'mdhd');
  mdhd.skip(mdhd.version === 1 ? 16 : 8);
  const timescale = mdhd.u32();
  const stbl = find(bytes, track, 'mdia/minf/stbl');
  if (!stbl) throw new Mp4Error('no stbl box in the video track');
  const box = (type) => find(bytes, stbl, type);

  const stsd = fullBox(bytes, box('stsd'), 'stsd');
  if (stsd.u32() < 1) throw new Mp4Error('stsd: no sample entry');
  const stsdBox = box('stsd');
  const [entry] = boxes(bytes, stsdBox.start + 8, stsdBox.end);
  if (!entry) throw new Mp4Error('stsd: no sample entry');
  const known = SAMPLE_ENTRIES[entry.type];
  if (!known) throw new Mp4Error(`video coded as ${entry.type}, which this reader does not name (it reads avc1, avc3, hvc1, hev1)`);
  // A visual sample entry: 6 reserved bytes, the data reference index, 16 bytes, width and height, 50 bytes, then its boxes.
  if (entry.start + 78 > entry.end) throw new Mp4Error(`${entry.type}: truncated`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const width = view.getUint16(entry.start + 24);
  const height = view.getUint16(entry.start + 26);
  const configBox = boxes(bytes, entry.start + 78, entry.end).find((b) => b.type === known[0]);
  if (!configBox) throw new Mp4Error(`${entry.type}: no ${known[0]} box`);
  const description = bytes.slice(configBox.start, configBox.end);
  const codec = known[1](entry.type, description);

  // Sizes.
  const stsz = fullBox(bytes, box('stsz'), 'stsz');
  const fixedSize = stsz.u32();
  const count = stsz.u32();
  if (count * Math.max(fixedSize, 1) > bytes.length) throw new Mp4Error(`stsz: ${count} samples, more than the file holds`);
  const sizes = Array.from({ length: count }, () => (fixedSize === 0 ? stsz.u32() : fixedSize));
  // Chunk offsets, then samples per chunk.
  const co = box('stco') ? fullBox(bytes, box('stco'), 'stco') : fullBox(bytes, box('co64'), 'stco or co64');
  const wide = !box('stco');
  const chunkOffsets = Array.from({ length: co.u32() }, () => (wide ? co.u64() : co.u32()));
  const stsc = fullBox(bytes, box('stsc'), 'stsc');
  const runs = Array.from({ length: stsc.u32() }, () => {
    const [firstChunk, perChunk] = [stsc.u32(), stsc.u32()];
    stsc.u32();
    return { firstChunk, perChunk };
  });
  const offsets = [];
  for (let r = 0; r < runs.length && offsets.length < count; r++) {
    const last = r + 1 < runs.length ? runs[r + 1].firstChunk - 1 : chunkOffsets.length;
    for (let chunk = runs[r].firstChunk; chunk <= last && offsets.length < count; chunk++) {
      if (chunk < 1 || chunk > chunkOffsets.length) throw new Mp4Error(`stsc: chunk ${chunk} has no offset in stco`);
      let at = chunkOffsets[chunk - 1];
      for (let s = 0; s < runs[r].perChunk && offsets.length < count; s++) {
        offsets.push(at);
        at += sizes[offsets.length - 1];
      }
    }
  }
  if (offsets.length < count) throw new Mp4Error(`stsc: ${offsets.length} of the ${count} samples placed in chunks`);
  // Decode times, presentation offsets, key frames.
  const stts = fullBox(bytes, box('stts'), 'stts');
  const times = [];
  let clock = 0;
  for (let e = stts.u32(); e > 0; e--) {
    const [n, delta] = [stts.u32(), stts.u32()];
    for (let i = 0; i < n && times.length < count; i++, clock += delta) times.push(clock);
  }
  if (times.length < count) throw new Mp4Error(`stts: times for ${times.length} of the ${count} samples`);
  if (box('ctts')) {
    const ctts = fullBox(bytes, box('ctts'), 'ctts');
    let s = 0;
    for (let e = ctts.u32(); e > 0; e--) {
      const n = ctts.u32();
      const shift = ctts.version === 1 ? ctts.i32() : ctts.u32();
      for (let i = 0; i < n && s < count; i++) times[s++] += shift;
    }
  }
  let keys = null;
  if (box('stss')) {
    const stss = fullBox(bytes, box('stss'), 'stss');
    keys = new Set(Array.from({ length: stss.u32() }, () => stss.u32() - 1));
  }
  const samples = sizes.map((size, i) => {
    if (offsets[i] + size > bytes.length) throw new Mp4Error(`sample ${i} runs past the end of the file (truncated?)`);
    return { offset: offsets[i], size, key: keys ? keys.has(i) : true, time: times[i], rank: 0 };
  });
  [...samples.keys()].sort((a, b) => samples[a].time - samples[b].time || a - b).forEach((s, rank) => (samples[s].rank = rank));
  return { codec, description, width, height, timescale, samples };
}
