// The package README's Node example, run as written (so it cannot rot
// again: it once called writeFile without importing it). The example is the
// first ```js block under "## Node" in pkg-config/README.md; it runs in a
// temporary folder where node_modules/surfel-slam is the built pkg/, on the
// bundled TUM fr3/teddy clip (in the repo, always present).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, symlinkSync, writeFileSync } from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { PKG, ROOT } from './long_run.mjs';
import { CLIP, plyVertexCount } from './sequence.mjs';

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
