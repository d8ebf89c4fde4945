// A minimal MP4 writer for test fixtures: one video track of coded samples
// (WebCodecs' EncodedVideoChunk bytes, or any bytes for the reader's own
// tests), as an iPhone's rgb.mp4 holds them. Not part of the page.

const u32 = (n) => [(n >>> 24) & 255, (n >>> 16) & 255, (n >>> 8) & 255, n & 255];
const u16 = (n) => [(n >>> 8) & 255, n & 255];
const ascii = (s) => [...s].map((c) => c.charCodeAt(0));

/** A box: size, type, then the payload's bytes (arrays of numbers or Uint8Arrays). */
function box(type, ...parts) {
  const payload = parts.flatMap((p) => Array.from(p));
  return [...u32(8 + payload.length), ...ascii(type), ...payload];
}
const fullBox = (type, version, ...parts) => box(type, [version, 0, 0, 0], ...parts);

/**
 * The bytes of an MP4 file with one video track.
 * `entry`: the sample entry's type ('avc1', 'hvc1', ...); `config`: its
 * configuration box `[type, bytes]` (['avcC', description]); `samples`:
 * `[{bytes, duration, shift, key}]` in decode order (`shift`: presentation
 * minus decode time, in `timescale` units); `perChunk`: samples a chunk;
 * `moovFirst`: the index before the media data (else after, as a phone
 * writes it); `ctts`: the ctts box's version (1: signed shifts).
 */
export function writeMp4({ entry = 'avc1', config, width, height, timescale = 600, samples, perChunk = 4, moovFirst = false, ctts = null }) {
  const ftyp = box('ftyp', ascii('isom'), u32(512), ascii('isomiso2avc1mp41'));
  const media = samples.flatMap((s) => Array.from(s.bytes));
  const mdatHeader = 8;
  const build = (mediaStart) => {
    const chunkOffsets = [];
    let at = mediaStart;
    samples.forEach((s, i) => {
      if (i % perChunk === 0) chunkOffsets.push(at);
      at += s.bytes.length;
    });
    const visual = [
      ...[0, 0, 0, 0, 0, 0],
      ...u16(1),
      ...new Array(16).fill(0),
      ...u16(width),
      ...u16(height),
      ...u32(0x00480000),
      ...u32(0x00480000),
      ...u32(0),
      ...u16(1),
      ...new Array(32).fill(0),
      ...u16(0x18),
      ...u16(0xffff),
    ];
    const stsd = fullBox('stsd', 0, u32(1), box(entry, visual, box(config[0], config[1])));
    const stts = fullBox('stts', 0, u32(samples.length), ...samples.map((s) => [...u32(1), ...u32(s.duration)]));
    const shifted = samples.some((s) => s.shift);
    const cttsBox = shifted ? fullBox('ctts', ctts ?? 0, u32(samples.length), ...samples.map((s) => [...u32(1), ...u32(s.shift >>> 0)])) : [];
    const keys = samples.map((s, i) => (s.key ? i + 1 : 0)).filter(Boolean);
    const stss = keys.length < samples.length ? fullBox('stss', 0, u32(keys.length), ...keys.map(u32)) : [];
    const stsc = fullBox('stsc', 0, u32(1), u32(1), u32(perChunk), u32(1));
    const stsz = fullBox('stsz', 0, u32(0), u32(samples.length), ...samples.map((s) => u32(s.bytes.length)));
    const stco = fullBox('stco', 0, u32(chunkOffsets.length), ...chunkOffsets.map(u32));
    const duration = samples.reduce((t, s) => t + s.duration, 0);
    const hdlr = fullBox('hdlr', 0, u32(0), ascii('vide'), new Array(12).fill(0), ascii('video\0'));
    const mdhd = fullBox('mdhd', 0, u32(0), u32(0), u32(timescale), u32(duration), u16(0x55c4), u16(0));
    const minf = box('minf', fullBox('vmhd', 0, new Array(8).fill(0)), box('dinf', fullBox('dref', 0, u32(1), fullBox('url ', 0))), box('stbl', stsd, stts, cttsBox, stss, stsc, stsz, stco));
    const tkhd = fullBox('tkhd', 0, u32(0), u32(0), u32(1), u32(0), u32(duration), new Array(52).fill(0), u32(width << 16), u32(height << 16));
    const mvhd = fullBox('mvhd', 0, u32(0), u32(0), u32(timescale), u32(duration), u32(0x00010000), u16(0x0100), new Array(70).fill(0), u32(2));
    return box('moov', mvhd, box('trak', tkhd, box('mdia', mdhd, hdlr, minf)));
  };
  if (moovFirst) {
    const size = build(0).length;
    const moov = build(ftyp.length + size + mdatHeader);
    return new Uint8Array([...ftyp, ...moov, ...box('mdat', media)]);
  }
  const moov = build(ftyp.length + mdatHeader);
  return new Uint8Array([...ftyp, ...box('mdat', media), ...moov]);
}
