// Meshing time and memory in wasm (single-threaded package, Node):
//   node tests/node/mesh_bench.mjs map.ply [more.ply ...] [--voxel-size M] [--repeat N]
// The maps are surfel PLYs as `surfel-slam run --ply` or `slam.exportPly()`
// write them. Prints per map the median ms of `meshSurfelPly` (PLY parse
// included) and the wasm memory before and after.
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const args = process.argv.slice(2);
let voxelSize = 0.01;
let repeat = 3;
const maps = [];
for (let i = 0; i < args.length; i++) {
  if (args[i] === '--voxel-size') voxelSize = Number(args[++i]);
  else if (args[i] === '--repeat') repeat = Number(args[++i]);
  else maps.push(args[i]);
}
if (maps.length === 0) {
  console.error('usage: node tests/node/mesh_bench.mjs map.ply [...] [--voxel-size M] [--repeat N]');
  process.exit(2);
}
const m = await import(pathToFileURL(path.join(root, 'pkg/surfel_slam.js')).href);
const wasm = await m.default({ module_or_path: await readFile(path.join(root, 'pkg/surfel_slam_bg.wasm')) });
const mib = (b) => (b / 1048576).toFixed(1);
for (const file of maps) {
  const ply = await readFile(file);
  const before = wasm.memory.buffer.byteLength;
  const times = [];
  let bytes = null;
  for (let r = 0; r < repeat; r++) {
    const t0 = performance.now();
    bytes = m.meshSurfelPly(ply, { format: 'glb', voxelSize });
    times.push(performance.now() - t0);
  }
  times.sort((a, b) => a - b);
  console.log(
    `${path.basename(file)}: median ${times[times.length >> 1].toFixed(0)} ms over ${repeat} (min ${times[0].toFixed(0)}), ` +
      `glb ${mib(bytes.length)} MiB, wasm memory ${mib(before)} -> ${mib(wasm.memory.buffer.byteLength)} MiB`,
  );
}
