// A minimal PNG encoder for test inputs (8/16-bit grey, RGB or RGBA, one fill
// value; optionally a forged header size), shared by the Node and browser tests.
import zlib from 'node:zlib';

const crcTable = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = crcTable[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/**
 * A PNG of `width` x `height`, `channels` (1, 3 or 4) of `bitDepth` (8 or 16),
 * filled with `value`; `claim` = [w, h] forges the header's size instead.
 */
export function encodePng(width, height, channels, bitDepth, value, claim = null) {
  const bytesPerPixel = (channels * bitDepth) / 8;
  const row = Buffer.alloc(1 + width * bytesPerPixel);
  for (let i = 1; i < row.length; i += bitDepth / 8) {
    if (bitDepth === 16) row.writeUInt16BE(value, i);
    else row[i] = value;
  }
  const raw = Buffer.concat(Array.from({ length: height }, () => row));
  const chunk = (type, data) => {
    const out = Buffer.alloc(12 + data.length);
    out.writeUInt32BE(data.length, 0);
    out.write(type, 4, 'latin1');
    data.copy(out, 8);
    out.writeUInt32BE(crc32(out.subarray(4, 8 + data.length)), 8 + data.length);
    return out;
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(claim ? claim[0] : width, 0);
  ihdr.writeUInt32BE(claim ? claim[1] : height, 4);
  ihdr[8] = bitDepth;
  ihdr[9] = { 1: 0, 3: 2, 4: 6 }[channels]; // grey, RGB, RGBA
  return new Uint8Array(
    Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', ihdr), chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]),
  );
}
