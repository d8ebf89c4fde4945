// Opens a dataset folder with the package's own parsers (as the page does)
// and reads its frames: shared by the Node tests.
import { readFileSync, existsSync } from 'node:fs';
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { listFiles } from './files.mjs';
import { ROOT } from './long_run.mjs';

export const SHARED = path.resolve(ROOT, '../shared/data');
export const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');

/**
 * `t.skip`s (and returns false) when `dir` is absent; throws instead when
 * CI=true, where ../shared/data must be present.
 */
export function requireDir(t, dir) {
  if (existsSync(dir)) return true;
  if (process.env.CI === 'true') throw new Error(`${dir} is absent and CI=true`);
  t.skip(`${dir} is absent (no ../shared/data)`);
  return false;
}

/** `{ sequence, frame(i) -> [colourBytes, depthBytes] }` of a dataset folder. */
export async function openSequence(pkg, dir) {
  const names = (await listFiles(dir)).sort();
  const layout = pkg.detectLayout(names);
  const texts = {};
  for (const f of layout.indexFiles) texts[f] = await readFile(path.join(dir, f), 'utf8');
  const sequence = pkg.parseSequence(names, texts, path.basename(dir));
  const frame = (i) => {
    const f = sequence.frames[i];
    return [new Uint8Array(readFileSync(path.join(dir, f.colour))), new Uint8Array(readFileSync(path.join(dir, f.depth)))];
  };
  return { sequence, frame };
}

/** Vertex count in a binary PLY's header. */
export function plyVertexCount(ply) {
  const head = Buffer.from(ply.subarray(0, Math.min(ply.length, 600))).toString('latin1');
  const m = /element vertex (\d+)\n/.exec(head);
  if (!m) throw new Error(`no vertex count in the PLY header: ${head}`);
  return Number(m[1]);
}
