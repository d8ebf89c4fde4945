// The package README's Node example, run as written (so it cannot rot
// again: it once called writeFile without importing it, and once handled two
// of the five layouts). The example is the first ```js block under "## Node"
// in pkg-config/README.md; it runs in a temporary folder where
// node_modules/surfel-slam is the built pkg/, on the bundled TUM fr3/teddy
// clip (in the repo, always present) and on a few of its frames written in
// each other layout the package reads (tests/node/datasets.mjs).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import { cpSync, existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, symlinkSync, writeFileSync } from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { loadPackage, PKG, ROOT } from './long_run.mjs';
import { CLIP, plyVertexCount } from './sequence.mjs';
import { makeIclNuim, makeRealSense, makeSevenScenes, makeStray } from './datasets.mjs';

const skip = existsSync(path.join(PKG, 'package.json')) ? false : `${PKG} is not built: run scripts/build.sh`;

/** The first ```js block after the heading `heading` in a Markdown text. */
export function codeBlockAfter(markdown, heading) {
  const at = markdown.indexOf(`\n${heading}\n`);
  assert.ok(at >= 0, `no "${heading}" heading`);
  const m = /```js\n([\s\S]*?)```/.exec(markdown.slice(at));
  assert.ok(m, `no js block under "${heading}"`);
  return m[1];
}

test("the package README's Node example runs as written", { skip, timeout: 300_000 }, () => {
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const example = codeBlockAfter(readme, '## Node (>= 18)');
  const dir = mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-readme-'));
  try {
    mkdirSync(path.join(dir, 'node_modules'));
    symlinkSync(PKG, path.join(dir, 'node_modules/surfel-slam'), 'dir');
    writeFileSync(path.join(dir, 'example.mjs'), example);
    const out = execFileSync(process.execPath, ['example.mjs', CLIP], { cwd: dir, encoding: 'utf8' });
    const frames = readFileSync(path.join(CLIP, 'rgb.txt'), 'utf8')
      .split('\n')
      .filter((l) => l.trim() && !l.startsWith('#')).length;
    assert.match(out, new RegExp(`^${frames} frames, \\d+ surfels`, 'm'), out);
    assert.match(out, /^ATE 0\.0\d+ m$/m, out);
    const surfels = Number(/frames, (\d+) surfels/.exec(out)[1]);
    assert.equal(plyVertexCount(readFileSync(path.join(dir, 'map.ply'))), surfels);
    const poses = readFileSync(path.join(dir, 'trajectory.txt'), 'utf8')
      .split('\n')
      .filter((l) => l.trim() && !l.startsWith('#'));
    assert.equal(poses.length, frames);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

/** A temporary folder where `node_modules/surfel-slam` is the built pkg/ and the example is `example.mjs`. */
function exampleDir(example) {
  const dir = mkdtempSync(path.join(os.tmpdir(), 'surfel-slam-readme-'));
  mkdirSync(path.join(dir, 'node_modules/@types'), { recursive: true });
  symlinkSync(PKG, path.join(dir, 'node_modules/surfel-slam'), 'dir');
  const nodeTypes = path.join(ROOT, 'node_modules/@types/node');
  if (existsSync(nodeTypes)) symlinkSync(nodeTypes, path.join(dir, 'node_modules/@types/node'), 'dir');
  writeFileSync(path.join(dir, 'example.mjs'), example);
  return dir;
}

const TSC = path.join(ROOT, 'node_modules/typescript/bin/tsc');

test("the package README's Node example passes tsc --strict against the package's types", { skip, timeout: 120_000 }, (t) => {
  if (!existsSync(TSC)) {
    if (process.env.CI) assert.fail(`no TypeScript at ${TSC}: run npm ci`);
    t.skip(`no TypeScript at ${TSC}: run npm ci`);
    return;
  }
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const dir = exampleDir(codeBlockAfter(readme, '## Node (>= 18)'));
  try {
    writeFileSync(
      path.join(dir, 'tsconfig.json'),
      JSON.stringify({
        compilerOptions: {
          strict: true,
          allowJs: true,
          checkJs: true,
          noEmit: true,
          target: 'es2022',
          module: 'nodenext',
          moduleResolution: 'nodenext',
          types: ['node'],
          skipLibCheck: false,
        },
        files: ['example.mjs'],
      }),
    );
    let out = '';
    try {
      out = execFileSync(process.execPath, [TSC, '-p', 'tsconfig.json'], { cwd: dir, encoding: 'utf8' });
    } catch (e) {
      assert.fail(`tsc --strict rejects the README example:\n${e.stdout}${e.stderr}`);
    }
    t.diagnostic(`tsc --strict: clean${out ? `\n${out}` : ''}`);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

test("the package README's Node example skips a missing and a truncated frame, naming them", { skip, timeout: 300_000 }, (t) => {
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const dir = exampleDir(codeBlockAfter(readme, '## Node (>= 18)'));
  const data = path.join(dir, 'damaged');
  try {
    cpSync(CLIP, data, { recursive: true });
    const rows = (file) => readFileSync(path.join(data, file), 'utf8').split('\n').filter((l) => l.trim() && !l.startsWith('#'));
    const colourGone = rows('rgb.txt')[3].split(/\s+/)[1];
    const depthCut = rows('depth.txt')[6].split(/\s+/)[1];
    rmSync(path.join(data, colourGone));
    const bytes = readFileSync(path.join(data, depthCut));
    writeFileSync(path.join(data, depthCut), bytes.subarray(0, bytes.length >> 1));
    const frames = rows('rgb.txt').length;

    const out = execFileSync(process.execPath, ['example.mjs', data], { cwd: dir, encoding: 'utf8' });
    t.diagnostic(out.split('\n').filter((l) => /skipped|warning/.test(l)).join('\n'));
    assert.match(out, new RegExp(`^frame 3 skipped: .*${path.basename(colourGone).replace('.', '\\.')}.*missing`, 'm'), out);
    assert.match(
      out,
      new RegExp(`^frame 6 skipped \\(.*${path.basename(depthCut).replace('.', '\\.')}\\): frame at timestamp [0-9.]+: .*depth image could not be decoded`, 'm'),
      out,
    );
    assert.match(out, new RegExp(`^${frames - 2} frames, \\d+ surfels, 2 skipped$`, 'm'), out);
    assert.match(out, /^ATE 0\.0\d+ m$/m, out);
    assert.doesNotMatch(out, /^warning:/m, 'the right preset: no settings warning');
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

/** Runs the example in `dir` on `folder`: { status, out (stdout), err (stderr) }, whatever the exit code. */
function runExample(dir, folder) {
  const r = spawnSync(process.execPath, ['example.mjs', folder], { cwd: dir, encoding: 'utf8' });
  return { status: r.status, out: r.stdout, err: r.stderr };
}

/** Few frames a layout: CI's time is short, and what is checked is that each layout runs at all. */
const LAYOUT_FRAMES = 6;

test("the package README's Node example runs a folder of every other layout the package reads", { skip, timeout: 300_000 }, (t) => {
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const dir = exampleDir(codeBlockAfter(readme, '## Node (>= 18)'));
  try {
    const data = path.join(dir, 'data');
    mkdirSync(data);
    // TUM RGB-D: the tests above run it on the whole clip.
    const layouts = [
      ['ICL-NUIM', makeIclNuim(CLIP, LAYOUT_FRAMES, data), LAYOUT_FRAMES, /^ATE \d/m],
      ['7-Scenes', makeSevenScenes(CLIP, LAYOUT_FRAMES, data).dir, LAYOUT_FRAMES, /^ATE \d/m],
      // 848x480: only sequence.intrinsics (camera_intrinsic.json) gives that size.
      ['RealSense 848x480', makeRealSense(CLIP, LAYOUT_FRAMES, data, 'realsense_848', 848).dir, LAYOUT_FRAMES, null],
      // Depth only: every frame's colour is null.
      ['Stray Scanner', makeStray(CLIP, LAYOUT_FRAMES, data).dir, LAYOUT_FRAMES, /^difference from the device's odometry \d/m],
    ];
    for (const [name, folder, frames, score] of layouts) {
      const r = runExample(dir, folder);
      t.diagnostic(`${name}: exit ${r.status}, ${r.out.split('\n').filter((l) => /frames|ATE|difference|skipped|warning/.test(l)).join(' | ')}`);
      assert.equal(r.status, 0, `${name}: ${r.out}${r.err}`);
      assert.doesNotMatch(r.out, /^frame \d+ skipped/m, `${name}: ${r.out}`);
      const m = new RegExp(`^${frames} frames, (\\d+) surfels, 0 skipped$`, 'm').exec(r.out);
      assert.ok(m && Number(m[1]) > 0, `${name}: ${r.out}`);
      assert.equal(plyVertexCount(readFileSync(path.join(dir, 'map.ply'))), Number(m[1]), name);
      if (score) assert.match(r.out, score, `${name}: ${r.out}`);
      rmSync(path.join(dir, 'map.ply'));
    }
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

test("the package README's Node example plays a Stray export cut short, and exits 1 writing nothing when no frame can be read", { skip, timeout: 300_000 }, () => {
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const dir = exampleDir(codeBlockAfter(readme, '## Node (>= 18)'));
  try {
    // The app stopped mid-write: the last odometry row cut off.
    const { dir: cut } = makeStray(CLIP, LAYOUT_FRAMES, dir, 'stray_cut');
    const csv = path.join(cut, 'odometry.csv');
    const text = readFileSync(csv, 'utf8').trimEnd();
    writeFileSync(csv, text.slice(0, text.length - 40));
    const rows = text.split('\n').length;
    let r = runExample(dir, cut);
    assert.equal(r.status, 0, r.out + r.err);
    const warnings = r.out.split('\n').filter((l) => l.startsWith('warning:'));
    assert.equal(warnings.length, 1, r.out);
    assert.match(warnings[0], new RegExp(`^warning: odometry\\.csv, line ${rows}: the last line is cut off`), r.out);
    assert.match(r.out, new RegExp(`^${LAYOUT_FRAMES} frames, [1-9]\\d* surfels, 0 skipped$`, 'm'), r.out);
    for (const f of ['map.ply', 'mesh.glb', 'trajectory.txt']) {
      assert.ok(existsSync(path.join(dir, f)), `${f} not written`);
      rmSync(path.join(dir, f));
    }

    // Every depth image half written: nothing tracked, exit 1, no files.
    const { dir: dead } = makeStray(CLIP, 3, dir, 'stray_dead');
    for (let i = 0; i < 3; i++) {
      const file = path.join(dead, 'depth', `${String(i).padStart(6, '0')}.png`);
      const bytes = readFileSync(file);
      writeFileSync(file, bytes.subarray(0, bytes.length >> 1));
    }
    r = runExample(dir, dead);
    assert.equal(r.status, 1, r.out + r.err);
    assert.match(r.err, /nothing was tracked: all 3 frames skipped/, r.err);
    for (const f of ['map.ply', 'mesh.glb', 'trajectory.txt']) assert.ok(!existsSync(path.join(dir, f)), `${f} written`);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

test("the package README's API table names every preset and layout kind the package has", { skip }, async () => {
  const m = await loadPackage();
  const readme = readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8');
  const row = (call) => {
    const line = readme.split('\n').find((l) => l.startsWith(`| \`${call}`));
    assert.ok(line, `no API row for ${call}`);
    return line;
  };
  const presetsRow = row('presets()');
  const names = m.presets().map((p) => p.name);
  assert.ok(names.length >= 7, names.join());
  for (const name of names) assert.ok(presetsRow.includes(`\`${name}\``), `presets() row lacks ${name}: ${presetsRow}`);
  // The layout kinds as the package's own typings give them.
  const dts = readFileSync(path.join(PKG, 'surfel_slam.d.ts'), 'utf8');
  const kinds = [.../export type LayoutKind = ([^;]+);/.exec(dts)?.[1].matchAll(/'([^']+)'/g) ?? []].map((k) => k[1]);
  assert.ok(kinds.length >= 5, kinds.join());
  const layoutRow = row('detectLayout(');
  for (const kind of kinds) assert.ok(layoutRow.includes(`'${kind}'`), `detectLayout row lacks '${kind}': ${layoutRow}`);
});
