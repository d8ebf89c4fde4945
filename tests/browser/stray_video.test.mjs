// A Stray Scanner scan's rgb.mp4 in the page: decoded by the browser
// (WebCodecs), frame i of the video colours depth frame i; a video the
// browser cannot decode (an iPhone's HEVC here: Debian's Chromium has no
// HEVC decoder) or a file that is no video leaves the scan on depth alone,
// said once. The video is made here: the bundled clip's colour frames encoded
// by Chromium's own H.264 encoder, written into an MP4 by
// tests/node/mp4-writer.mjs.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { startBrowser, openPage, openModulePage, waitForStatus, saveScreenshot, skipUnlessReady, canvasPng, decodePng } from './helpers.mjs';
import { CLIP, makeStray, tempDir, writeArchive } from '../node/datasets.mjs';
import { writeMp4 } from '../node/mp4-writer.mjs';

const FRAMES = 12;
const [WIDTH, HEIGHT] = [640, 480];

/** The clip's colour image nearest in time to each of the scan's frames (`poses` rows start with the time). */
function colourFiles(poses) {
  const rows = fs
    .readFileSync(path.join(CLIP, 'rgb.txt'), 'utf8')
    .split('\n')
    .filter((l) => l.trim() && !l.startsWith('#'))
    .map((l) => l.trim().split(/\s+/));
  return poses.map(([t]) => {
    const nearest = rows.reduce((a, b) => (Math.abs(Number(b[0]) - t) < Math.abs(Number(a[0]) - t) ? b : a));
    return path.join(CLIP, nearest[1]);
  });
}

/** H.264 (WebCodecs, in `page`) of the PNG files: an MP4's bytes, a key frame every 4. */
async function h264Mp4(page, files) {
  const pngs = files.map((f) => fs.readFileSync(f).toString('base64'));
  const encoded = await page.evaluate(
    async ({ pngs, width, height }) => {
      const bytes = (b64) => Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const base64 = (u8) => btoa(String.fromCharCode(...u8));
      const chunks = [];
      let description = null;
      const encoder = new VideoEncoder({
        output: (chunk, meta) => {
          if (meta?.decoderConfig?.description) description = base64(new Uint8Array(meta.decoderConfig.description));
          const data = new Uint8Array(chunk.byteLength);
          chunk.copyTo(data);
          chunks.push({ key: chunk.type === 'key', data: Array.from(data) });
        },
        error: (e) => {
          throw e;
        },
      });
      encoder.configure({ codec: 'avc1.42001f', width, height, bitrate: 8_000_000, framerate: 30, avc: { format: 'avc' } });
      for (let i = 0; i < pngs.length; i++) {
        const bitmap = await createImageBitmap(new Blob([bytes(pngs[i])]));
        const frame = new VideoFrame(bitmap, { timestamp: i * 33_333, duration: 33_333 });
        encoder.encode(frame, { keyFrame: i % 4 === 0 });
        frame.close();
        bitmap.close();
      }
      await encoder.flush();
      return { description, chunks };
    },
    { pngs, width: WIDTH, height: HEIGHT },
  );
  assert.ok(encoded.description, 'the encoder gave its avcC');
  assert.equal(encoded.chunks.length, files.length);
  const avcC = Uint8Array.from(Buffer.from(encoded.description, 'base64'));
  const samples = encoded.chunks.map((c) => ({ bytes: Uint8Array.from(c.data), duration: 1001, key: c.key, shift: 0 }));
  return writeMp4({ entry: 'avc1', config: ['avcC', avcC], width: WIDTH, height: HEIGHT, timescale: 30_000, samples });
}

/** An iPhone-like rgb.mp4 header (HEVC, Main profile) over samples that are no video. */
const hevcMp4 = () =>
  writeMp4({
    entry: 'hvc1',
    config: ['hvcC', new Uint8Array([1, 0x01, 0x60, 0, 0, 0, 0xb0, 0, 0, 0, 0, 0, 93, 0xf0, 0, 0xfc, 0xfd, 0xf8, 0xf8, 0, 0, 0x0f, 0])],
    width: 1920,
    height: 1440,
    samples: Array.from({ length: FRAMES }, (_, i) => ({ bytes: new Uint8Array(16).fill(i), duration: 10, key: i === 0, shift: 0 })),
  });

/** Share of the map canvas's pixels with colour (channels apart by more than 24 of 255). */
async function colouredShare(page) {
  const { width, height, channels, data } = decodePng(await canvasPng(page));
  let coloured = 0;
  for (let i = 0; i < width * height; i++) {
    const [r, g, b] = [data[i * channels], data[i * channels + 1], data[i * channels + 2]];
    if (Math.max(r, g, b) - Math.min(r, g, b) > 24) coloured++;
  }
  return coloured / (width * height);
}

test('the video reader: frame i of rgb.mp4 is the i-th picture, asked for in any order', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-video-');
  const { poses } = makeStray(CLIP, FRAMES, tmp);
  const files = colourFiles(poses);
  const env = await startBrowser();
  try {
    const { page, errors } = await openModulePage(env);
    const mp4 = await h264Mp4(page, files);
    const result = await page.evaluate(
      async ({ mp4, pngs }) => {
        const { VideoColour } = await import('/video-colour.js');
        const bytes = (b64) => Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
        const canvas = new OffscreenCanvas(64, 48);
        const context = canvas.getContext('2d', { willReadFrequently: true });
        /** Grey levels of an image's bytes at 64x48. */
        const thumbnail = async (buffer) => {
          const bitmap = await createImageBitmap(new Blob([buffer]), { resizeWidth: 64, resizeHeight: 48, resizeQuality: 'medium' });
          context.drawImage(bitmap, 0, 0);
          bitmap.close();
          const rgba = context.getImageData(0, 0, 64, 48).data;
          return Array.from({ length: 64 * 48 }, (_, i) => (rgba[4 * i] + rgba[4 * i + 1] + rgba[4 * i + 2]) / 3);
        };
        const video = new VideoColour(bytes(mp4));
        const sources = await Promise.all(pngs.map((p) => thumbnail(bytes(p))));
        const firstPass = [];
        const sizes = [];
        for (let i = 0; i < video.frames; i++) {
          const png = new Uint8Array(await video.png(i, [256, 192]));
          firstPass.push(png);
          const view = new DataView(png.buffer);
          sizes.push([view.getUint32(16), view.getUint32(20)]);
        }
        // Each decoded frame against every source picture: mean absolute grey difference.
        const nearest = [];
        for (const png of firstPass) {
          const grey = await thumbnail(png);
          const differences = sources.map((s) => s.reduce((sum, v, k) => sum + Math.abs(v - grey[k]), 0) / s.length);
          const best = differences.indexOf(Math.min(...differences));
          nearest.push({ best, difference: differences[best], next: Math.min(...differences.filter((_, j) => j !== best)) });
        }
        // Out of order, as a replay or a continued session asks: the same pictures.
        const same = [];
        for (const i of [5, 2, 11, 0, 7, 7, 3]) {
          const png = new Uint8Array(await video.png(i, [256, 192]));
          same.push(png.length === firstPass[i].length && png.every((v, k) => v === firstPass[i][k]));
        }
        // Asked for all at once, as the frame feed reads ahead: each its own picture.
        const fresh = new VideoColour(bytes(mp4));
        const together = await Promise.all(firstPass.map((_, i) => fresh.png(i, [256, 192])));
        const sameTogether = together.map((b, i) => {
          const png = new Uint8Array(b);
          return png.length === firstPass[i].length && png.every((v, k) => v === firstPass[i][k]);
        });
        let beyond = null;
        try {
          await video.png(video.frames, [256, 192]);
        } catch (e) {
          beyond = e.message;
        }
        return { frames: video.frames, codec: video.video.codec, sizes, nearest, same, sameTogether, beyond };
      },
      { mp4: Buffer.from(mp4).toString('base64'), pngs: files.map((f) => fs.readFileSync(f).toString('base64')) },
    );
    t.diagnostic(`${result.codec}: ${JSON.stringify(result.nearest.map((n) => [n.best, n.difference.toFixed(1), n.next.toFixed(1)]))}`);
    assert.equal(result.frames, FRAMES);
    assert.match(result.codec, /^avc1\./);
    assert.deepEqual(result.sizes, Array(FRAMES).fill([256, 192]));
    result.nearest.forEach((n, i) => {
      assert.equal(n.best, i, `decoded frame ${i} looks most like picture ${n.best}`);
      assert.ok(n.difference < 6, `frame ${i}: ${n.difference} grey levels from its picture`);
    });
    assert.deepEqual(result.same, Array(7).fill(true), 'a frame asked for again is the same picture');
    assert.deepEqual(result.sameTogether, Array(FRAMES).fill(true), 'frames asked for at once are each their own picture');
    assert.match(result.beyond ?? '', /has 12 frames, not a frame 12/);
    assert.deepEqual(errors, []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('a Stray Scanner scan plays in colour from its rgb.mp4; a video the browser cannot decode leaves it on depth alone, said once', { timeout: 300_000 }, async (t) => {
  if (skipUnlessReady(t)) return;
  const tmp = tempDir('surfel-slam-page-stray-video-');
  const env = await startBrowser();
  try {
    const { page, consoleErrors } = await openPage(env, '/?sample=0');
    await waitForStatus(page, (s) => s.ready, { timeoutMs: 60_000 });
    const hevcSupported = await page.evaluate(async () => (await VideoDecoder.isConfigSupported({ codec: 'hvc1.1.6.L93.B0' })).supported);
    /** The scan as folder `name` (or a .zip of it), with `video` as its rgb.mp4 (none when null), played to its end. */
    const play = async (name, video, zipped = false) => {
      const { dir, poses } = makeStray(CLIP, FRAMES, tmp, name);
      if (video) fs.writeFileSync(path.join(dir, 'rgb.mp4'), typeof video === 'function' ? await video(poses) : video);
      if (zipped) await page.locator('#archive-input').setInputFiles(writeArchive(dir, name, tmp, 'zip'));
      else await page.locator('#folder-input').setInputFiles(dir);
      const status = await waitForStatus(page, (s) => s.sequence === name && s.done && !s.playing && s.framesProcessed === FRAMES, {
        timeoutMs: 120_000,
        log: (m) => t.diagnostic(m),
      });
      await page.waitForTimeout(300);
      const info = await page.locator('#sequence-info').textContent();
      const coloured = await colouredShare(page);
      t.diagnostic(`${name}: ${info}; ${status.framesColourFromVideo} frames coloured from the video, ${status.framesLost} lost, ${(100 * coloured).toFixed(1)} % of the map's pixels coloured, ${status.positionErrorCm} cm from the odometry`);
      assert.equal(status.error, null, status.error);
      assert.equal(status.sequenceKind, 'stray-scanner');
      assert.equal(status.framesFailed, 0);
      assert.equal(status.framesLost, 0);
      assert.ok(Number.isFinite(status.positionErrorCm) && status.positionErrorCm < 2, `${status.positionErrorCm} cm from the odometry`);
      return { status, info, coloured };
    };

    const inColour = await play('scan_h264', (poses) => h264Mp4(page, colourFiles(poses)));
    saveScreenshot('stray-scanner-video-page.png', await page.screenshot());
    assert.match(inColour.info, /colour from scan_h264\/rgb\.mp4 \(avc1\.42\w{4}, 640x480, 12 frames\)/);
    assert.equal(inColour.status.framesColourFromVideo, FRAMES);
    assert.equal(inColour.status.framesVideoFailed, 0);
    // Reset and played again: the video is decoded again from its first frame, every frame in colour.
    await page.locator('#reset-button').click();
    await waitForStatus(page, (s) => s.framesProcessed === 0 && !s.playing && !s.done, { timeoutMs: 30_000 });
    await page.locator('#play-button').click();
    const replayed = await waitForStatus(page, (s) => s.sequence === 'scan_h264' && s.done && !s.playing && s.framesProcessed === FRAMES && s.framesColourFromVideo === FRAMES, {
      timeoutMs: 120_000,
      log: (m) => t.diagnostic(m),
    });
    assert.equal(replayed.framesLost, 0);
    assert.equal(replayed.framesVideoFailed, 0);
    assert.equal(replayed.positionErrorCm, inColour.status.positionErrorCm, 'played again, the same run');
    assert.equal(replayed.surfels, inColour.status.surfels, 'played again, the same map');

    // Dropped as a zip: the video read out of the archive.
    const zipped = await play('scan_zip', (poses) => h264Mp4(page, colourFiles(poses)), true);
    assert.match(zipped.info, /colour from scan_zip\/rgb\.mp4 \(avc1/);
    assert.equal(zipped.status.framesColourFromVideo, FRAMES);

    const notVideo = await play('scan_text', 'a file that is no video');
    assert.match(notVideo.info, /scan_text\/rgb\.mp4: not an MP4 file .*: playing on depth alone \(grey map\)/);
    assert.equal(notVideo.status.framesColourFromVideo, 0);
    // The teddy covers a few per cent of the canvas: in colour it is coloured, on depth alone grey.
    assert.ok(inColour.coloured > 0.01 && inColour.coloured > 5 * notVideo.coloured, `the map in colour (${inColour.coloured}) against grey (${notVideo.coloured})`);

    const hevc = await play('scan_hevc', hevcMp4());
    if (hevcSupported) {
      // A browser with an HEVC decoder tries it: these samples are no video, so the frames play on depth alone, said once.
      assert.ok(hevc.status.framesVideoFailed > 0);
      assert.equal(hevc.status.warnings.filter((w) => /^colour: /.test(w)).length, 1, 'said once');
    } else {
      assert.match(hevc.info, /scan_hevc\/rgb\.mp4: this browser cannot decode hvc1\.1\.6\.L93\.B0 video: playing on depth alone/);
    }
    assert.equal(hevc.status.framesColourFromVideo, 0);

    const none = await play('scan_depth_only', null);
    assert.match(none.info, /no colour images or rgb\.mp4: playing on depth alone/);
    assert.deepEqual(consoleErrors.filter((e) => /panicked|unreachable/.test(e)), []);
  } finally {
    await env.close();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});
