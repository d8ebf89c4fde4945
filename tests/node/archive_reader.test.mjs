// The wasm ArchiveReader (the CLI's archive reader, exported for the page)
// under Node: the bundled clip packed as .tgz, .tar and .zip, read from a
// Uint8Array and piece by piece through a read(offset, length) callback (as
// the page reads a picked File); the names go through detectLayout /
// parseSequence like a folder's, the frames track. Corrupt and truncated
// archives throw an Error naming the archive, and the module keeps working.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG } from './long_run.mjs';
import { CLIP, listTree, tempDir, tumSubset, writeArchive } from './datasets.mjs';

const skip = fs.existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;
const FRAMES = 12;

/** A read(offset, length) source over a file on disk, counting the bytes it hands out. */
function fileSource(file) {
  const fd = fs.openSync(file, 'r');
  const size = fs.fstatSync(fd).size;
  const source = {
    size,
    served: 0,
    read(offset, length) {
      const buf = Buffer.alloc(length);
      const n = fs.readSync(fd, buf, 0, length, offset);
      source.served += n;
      return new Uint8Array(buf.buffer, buf.byteOffset, n);
    },
    close: () => fs.closeSync(fd),
  };
  return source;
}

test('archives list, read and play like the folder', { skip, timeout: 300_000 }, async (t) => {
  const m = await loadPackage();
  const tmp = tempDir('surfel-slam-archive-');
  try {
    const folder = tumSubset(CLIP, FRAMES, path.join(tmp, 'clip'));
    const folderNames = listTree(folder);
    for (const ext of ['tgz', 'tar', 'zip']) {
      const file = writeArchive(folder, 'rgbd_dataset_freiburg3_clip', tmp, ext);
      const source = fileSource(file);
      for (const [how, input] of [
        ['callback', source],
        ['bytes', new Uint8Array(fs.readFileSync(file))],
      ]) {
        const reader = new m.ArchiveReader(input, path.basename(file));
        try {
          assert.equal(reader.format, ext === 'tgz' ? 'tar.gz' : ext);
          assert.deepEqual(reader.names, folderNames.map((n) => `rgbd_dataset_freiburg3_clip/${n}`), `${ext} ${how}: names`);
          const layout = m.detectLayout(reader.names);
          const texts = {};
          for (const f of layout.indexFiles) texts[f] = new TextDecoder().decode(reader.read(f));
          const seq = m.parseSequence(reader.names, texts, 'rgbd_dataset_freiburg3_clip');
          assert.equal(seq.kind, 'tum');
          assert.equal(seq.frames.length, FRAMES);
          assert.ok(seq.groundTruth.length > 0);
          // Frames in order through a Slam; bytes equal the folder's.
          const slam = new m.Slam(seq.preset);
          try {
            for (const f of seq.frames) {
              const colour = reader.read(f.colour);
              const depth = reader.read(f.depth);
              const rel = (p) => p.slice('rgbd_dataset_freiburg3_clip/'.length);
              assert.ok(Buffer.from(colour).equals(fs.readFileSync(path.join(folder, rel(f.colour)))), f.colour);
              assert.ok(Buffer.from(depth).equals(fs.readFileSync(path.join(folder, rel(f.depth)))), f.depth);
              const r = slam.pushFrame(colour, depth, f.timestamp);
              assert.notEqual(r.verdict, 'lost', `${ext} ${how}: frame ${f.index}`);
            }
            const ate = m.ateTum(slam.trajectoryTum(), seq.groundTruthTum);
            t.diagnostic(`${ext} (${how}): ${seq.frames.length} frames, ATE ${(ate.rmse * 100).toFixed(2)} cm over ${ate.pairs} poses`);
            assert.ok(ate.rmse < 0.03, `ATE ${ate.rmse} m`);
          } finally {
            slam.free();
          }
          // Backwards reads (a tar.gz restarts its stream) give the same bytes.
          const last = seq.frames[seq.frames.length - 1];
          const first = seq.frames[0];
          assert.ok(Buffer.from(reader.read(last.depth)).equals(Buffer.from(reader.read(last.depth))));
          assert.ok(Buffer.from(reader.read(first.colour)).length > 1000);
          assert.throws(() => reader.read('rgbd_dataset_freiburg3_clip/rgb/nothing.png'), /nothing\.png is missing/);
        } finally {
          reader.free();
        }
      }
      if (ext === 'zip') {
        // Random access: listing and reading one frame read far less than the whole file.
        const lazy = fileSource(file);
        const reader = new m.ArchiveReader(lazy, path.basename(file));
        reader.read(reader.names.find((n) => n.endsWith('.png')));
        t.diagnostic(`zip: listing + one image read ${lazy.served} of ${lazy.size} bytes`);
        assert.ok(lazy.served < lazy.size / 4, `read ${lazy.served} of ${lazy.size} bytes`);
        reader.free();
        lazy.close();
      }
      source.close();
    }
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

test('corrupt and truncated archives throw an Error naming them', { skip, timeout: 120_000 }, async (t) => {
  const m = await loadPackage();
  const tmp = tempDir('surfel-slam-archive-bad-');
  try {
    const folder = tumSubset(CLIP, 3, path.join(tmp, 'clip'));
    const cases = [];
    for (const ext of ['tgz', 'tar', 'zip']) {
      const bytes = fs.readFileSync(writeArchive(folder, 'clip', tmp, ext));
      cases.push([`truncated.${ext}`, bytes.subarray(0, Math.floor(bytes.length / 2))]);
    }
    cases.push(['garbage.zip', Buffer.from('not an archive at all'.repeat(50))]);
    cases.push(['empty.tar', Buffer.alloc(0)]);
    for (const [name, bytes] of cases) {
      let message = null;
      try {
        new m.ArchiveReader(new Uint8Array(bytes), name).free();
      } catch (e) {
        message = e.message;
      }
      t.diagnostic(`${name}: ${message}`);
      assert.ok(message, `${name}: opened`);
      assert.ok(message.includes(name), `${name}: ${message}`);
    }
    assert.throws(() => new m.ArchiveReader({ size: 10 }, 'x.zip'), /x\.zip: the archive source must be/);
    assert.throws(() => new m.ArchiveReader(42, 'x.zip'), /x\.zip: the archive source must be/);
    const throwing = { size: 4096, read: () => { throw new Error('disk on fire'); } };
    assert.throws(() => new m.ArchiveReader(throwing, 'x.tgz'), /x\.tgz: cannot read: disk on fire/);
    const lying = { size: 1 << 20, read: () => new Uint8Array(0) };
    assert.throws(() => new m.ArchiveReader(lying, 'x.tgz'), /x\.tgz/);
    // The module is alive: a good archive still opens.
    const ok = new m.ArchiveReader(new Uint8Array(fs.readFileSync(writeArchive(folder, 'clip', tmp, 'zip'))), 'ok.zip');
    assert.ok(ok.names.length > 3);
    ok.free();
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});
