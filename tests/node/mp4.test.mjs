// The page's MP4 reader (www/mp4.js), which lists a Stray Scanner rgb.mp4's
// video samples for the browser's VideoDecoder: sample tables, presentation
// order with B-frames, codec names, and a clear error for each malformed file.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { parseMp4, Mp4Error } from '../../www/mp4.js';
import { writeMp4 } from './mp4-writer.mjs';

// An avcC payload: version 1, profile 0x64 (High), compatibility 0, level 0x1f.
const AVCC = new Uint8Array([1, 0x64, 0x00, 0x1f, 0xff, 0xe0, 0x00]);
// An iPhone's hvcC head: Main profile, compatibility flags 0x60000000, constraint 0xB0, level 93 (3.1).
const HVCC = new Uint8Array([1, 0x01, 0x60, 0, 0, 0, 0xb0, 0, 0, 0, 0, 0, 93, 0xf0, 0, 0xfc, 0xfd, 0xf8, 0xf8, 0, 0, 0x0f, 0]);

/** Samples whose bytes say their decode index, of lengths that differ. */
const samples = (n, extra = {}) =>
  Array.from({ length: n }, (_, i) => ({ bytes: new Uint8Array(3 + (i % 4)).fill(i + 1), duration: 20, key: i % 5 === 0, shift: 0, ...(extra[i] ?? {}) }));

test('lists the samples of a phone-style file (index after the data), their bytes, keys and order', () => {
  const s = samples(11);
  for (const moovFirst of [false, true]) {
    for (const perChunk of [1, 3, 11]) {
      const bytes = writeMp4({ config: ['avcC', AVCC], width: 1920, height: 1440, samples: s, perChunk, moovFirst });
      const video = parseMp4(bytes);
      assert.equal(video.codec, 'avc1.64001f');
      assert.deepEqual(Array.from(video.description), Array.from(AVCC));
      assert.equal(video.width, 1920);
      assert.equal(video.height, 1440);
      assert.equal(video.timescale, 600);
      assert.equal(video.samples.length, 11);
      video.samples.forEach((sample, i) => {
        assert.deepEqual(Array.from(bytes.subarray(sample.offset, sample.offset + sample.size)), Array.from(s[i].bytes), `sample ${i}, ${perChunk} a chunk`);
        assert.equal(sample.key, i % 5 === 0);
        assert.equal(sample.time, 20 * i);
        assert.equal(sample.rank, i);
      });
    }
  }
});

test('B-frames: a sample decoded before the ones it is shown after gets its place in presentation order', () => {
  // Decode order I P B B P B B (shown I B B P B B P): the P frames are shifted later.
  const shifts = [20, 60, 0, 0, 60, 0, 0];
  const s = samples(7).map((x, i) => ({ ...x, shift: shifts[i] }));
  for (const ctts of [0, 1]) {
    const video = parseMp4(writeMp4({ config: ['avcC', AVCC], width: 64, height: 48, samples: s, ctts }));
    assert.deepEqual(
      video.samples.map((x) => x.rank),
      [0, 3, 1, 2, 6, 4, 5],
    );
  }
});

test('names HEVC as WebCodecs does (an iPhone records hvc1)', () => {
  const video = parseMp4(writeMp4({ entry: 'hvc1', config: ['hvcC', HVCC], width: 1920, height: 1440, samples: samples(2) }));
  assert.equal(video.codec, 'hvc1.1.6.L93.B0');
  const hev = parseMp4(writeMp4({ entry: 'hev1', config: ['hvcC', HVCC], width: 1920, height: 1440, samples: samples(2) }));
  assert.equal(hev.codec, 'hev1.1.6.L93.B0');
});

test('a malformed file is refused, saying what is wrong', () => {
  const good = writeMp4({ config: ['avcC', AVCC], width: 64, height: 48, samples: samples(6) });
  const refused = (bytes, pattern) => assert.throws(() => parseMp4(bytes), (e) => e instanceof Mp4Error && pattern.test(e.message), String(pattern));
  refused(new TextEncoder().encode('not a video at all, just text'), /not an MP4 file/);
  refused(new Uint8Array(0), /not an MP4 file/);
  refused(good.subarray(0, good.length - 40), /truncated/);
  // The media data cut short: the index points past the end.
  const moovFirst = writeMp4({ config: ['avcC', AVCC], width: 64, height: 48, samples: samples(6), moovFirst: true });
  const cut = moovFirst.slice(0, moovFirst.length - 5);
  const view = new DataView(cut.buffer);
  // Shrink the mdat box to what is left, so that the boxes themselves parse.
  const mdatAt = moovFirst.length - 8 - samples(6).reduce((n, x) => n + x.bytes.length, 0);
  view.setUint32(mdatAt, cut.length - mdatAt);
  refused(cut, /sample \d+ runs past the end/);
  refused(writeMp4({ entry: 'vp09', config: ['vpcC', new Uint8Array(8)], width: 64, height: 48, samples: samples(2) }), /vp09/);
  refused(writeMp4({ entry: 'avc1', config: ['colr', new Uint8Array(8)], width: 64, height: 48, samples: samples(2) }), /no avcC box/);
  refused(writeMp4({ entry: 'hvc1', config: ['hvcC', new Uint8Array(4)], width: 64, height: 48, samples: samples(2) }), /hvcC: truncated/);
  // An audio-only file: no video track.
  const audio = good.slice();
  const at = Buffer.from(audio).indexOf('vide');
  audio.set([0x73, 0x6f, 0x75, 0x6e], at); // 'soun'
  refused(audio, /no video track/);
});
