// Meshes and 3D files from the built npm package (pkg/) under Node:
// `node --test tests/node/`. The `.glb` files (a mesh and a point cloud, of
// a synthetic sphere, of an empty map and of 10 real ICL-NUIM frames) must
// pass the Khronos glTF validator (npm `gltf-validator`) with 0 errors; PLY
// and OBJ come back with the counts the header / lines announce.
// Skipped cleanly when pkg/ is absent (and the ICL part without ../shared/data).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFile, readdir } from 'node:fs/promises';
import { existsSync } from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import validator from 'gltf-validator';

const here = path.dirname(fileURLToPath(import.meta.url));
const root = path.resolve(here, '../..');
const pkgDir = path.join(root, 'pkg');
const dataDir = path.join(root, '../shared/data/icl_office_kt0');

const built = existsSync(path.join(pkgDir, 'package.json'));
const skipNoPkg = built ? false : 'pkg/ is not built (run scripts/build.sh)';
const ciWithoutData = process.env.CI === 'true' && !existsSync(dataDir);
const skipNoData = skipNoPkg || (existsSync(dataDir) || ciWithoutData ? false : `${dataDir} is absent (no ../shared/data)`);

let modulePromise = null;
async function load() {
  modulePromise ??= (async () => {
    const m = await import(pathToFileURL(path.join(pkgDir, 'surfel_slam.js')).href);
    await m.default({ module_or_path: await readFile(path.join(pkgDir, 'surfel_slam_bg.wasm')) });
    return m;
  })();
  return modulePromise;
}

/** Surfels on a sphere (normals out) as a binary PLY, the layout exportPly writes. */
function spherePly(n, radius, centre) {
  const header =
    'ply\nformat binary_little_endian 1.0\n' +
    `element vertex ${n}\n` +
    'property float x\nproperty float y\nproperty float z\n' +
    'property float nx\nproperty float ny\nproperty float nz\n' +
    'property uchar red\nproperty uchar green\nproperty uchar blue\n' +
    'property float radius\nproperty float confidence\nend_header\n';
  const stride = 35;
  const bytes = new Uint8Array(header.length + n * stride);
  bytes.set(new TextEncoder().encode(header));
  const view = new DataView(bytes.buffer, header.length);
  const golden = Math.PI * (3 - Math.sqrt(5));
  for (let i = 0; i < n; i++) {
    const y = 1 - (2 * (i + 0.5)) / n;
    const r = Math.sqrt(1 - y * y);
    const d = [r * Math.cos(golden * i), y, r * Math.sin(golden * i)];
    const o = i * stride;
    for (let k = 0; k < 3; k++) {
      view.setFloat32(o + 4 * k, centre[k] + radius * d[k], true);
      view.setFloat32(o + 12 + 4 * k, d[k], true);
    }
    view.setUint8(o + 24, Math.round(127.5 * (y + 1)));
    view.setUint8(o + 25, 90);
    view.setUint8(o + 26, 200);
    view.setFloat32(o + 27, 0.004, true);
    view.setFloat32(o + 31, 20, true);
  }
  return bytes;
}

async function validate(bytes, what) {
  const report = await validator.validateBytes(new Uint8Array(bytes), { maxIssues: 100 });
  const errors = report.issues.messages.filter((m) => m.severity === 0);
  assert.equal(report.issues.numErrors, 0, `${what}: ${JSON.stringify(errors.slice(0, 5))}`);
  return report;
}

function plyCounts(bytes) {
  const head = new TextDecoder().decode(bytes.subarray(0, 1024));
  const count = (name) => Number(head.match(new RegExp(`element ${name} (\\d+)`))?.[1]);
  return { vertices: count('vertex'), faces: count('face') };
}

test('a sphere of surfels meshes to a valid glTF, PLY and OBJ, with progress', { skip: skipNoPkg }, async () => {
  const m = await load();
  const ply = spherePly(20000, 0.15, [0.1, -0.2, 1.2]);
  const fractions = [];
  const glb = m.meshSurfelPly(ply, { format: 'glb', voxelSize: 0.01 }, (f) => fractions.push(f));
  assert.ok(fractions.length > 10 && fractions.at(-1) === 1, `progress ${fractions}`);
  assert.ok(fractions.every((f, i) => i === 0 || f >= fractions[i - 1]));
  const report = await validate(glb, 'sphere mesh');
  const info = report.info;
  assert.equal(info.drawCallCount, 1);
  assert.ok(info.totalVertexCount > 2000, `${info.totalVertexCount} vertices`);
  assert.ok(info.totalTriangleCount > 4000, `${info.totalTriangleCount} triangles`);

  const meshPly = m.meshSurfelPly(ply, { format: 'ply' });
  const counts = plyCounts(meshPly);
  assert.equal(counts.vertices, info.totalVertexCount);
  assert.equal(counts.faces, info.totalTriangleCount);
  const obj = new TextDecoder().decode(m.meshSurfelPly(ply, { format: 'obj' }));
  assert.equal(obj.split('\n').filter((l) => l.startsWith('f ')).length, counts.faces);
  assert.equal(obj.split('\n').filter((l) => l.startsWith('v ')).length, counts.vertices);

  // Coarser voxels, fewer vertices (about a quarter at twice the edge).
  const coarse = await validate(m.meshSurfelPly(ply, { voxelSize: 0.02 }), 'coarse sphere');
  const ratio = info.totalVertexCount / coarse.info.totalVertexCount;
  assert.ok(ratio > 3 && ratio < 5, `${ratio}`);
});

test('bad options and bad files throw, and the module keeps working', { skip: skipNoPkg }, async () => {
  const m = await load();
  const ply = spherePly(2000, 0.1, [0, 0, 1]);
  assert.throws(() => m.meshSurfelPly(ply, { format: 'stl' }), /format/);
  assert.throws(() => m.meshSurfelPly(ply, { voxelSize: 0 }), /voxel size/);
  assert.throws(() => m.meshSurfelPly(ply, { voxelSize: 'big' }), /voxelSize/);
  assert.throws(() => m.meshSurfelPly(ply, { voxelsize: 0.01 }), /unknown mesh option/);
  assert.throws(() => m.meshSurfelPly(new Uint8Array([1, 2, 3]), {}), /PLY/);
  assert.throws(() => m.meshSurfelPly(ply.subarray(0, ply.length - 7), {}), /truncated/);
  // A throwing progress callback does not stop the meshing.
  const glb = m.meshSurfelPly(ply, {}, () => { throw new Error('ignored'); });
  await validate(glb, 'after errors');
});

test('an empty map exports valid files', { skip: skipNoPkg }, async () => {
  const m = await load();
  const slam = new m.Slam('icl-nuim');
  const mesh = slam.exportMesh(undefined);
  await validate(mesh, 'empty mesh');
  await validate(slam.exportGlbPoints(), 'empty points');
  assert.equal(plyCounts(slam.exportMesh({ format: 'ply' })).faces, 0);
  slam.free();
});

test('10 ICL-NUIM frames: mesh and points pass the glTF validator', { skip: skipNoData }, async () => {
  assert.ok(!ciWithoutData, `CI=true but ${dataDir} is absent`);
  const m = await load();
  const assoc = (await readFile(path.join(dataDir, 'associations.txt'), 'utf8'))
    .split('\n').map((l) => l.trim().split(/\s+/)).filter((w) => w.length === 4);
  const slam = new m.Slam('icl-nuim');
  for (const [t, depth, , rgb] of assoc.slice(0, 10)) {
    const [c, d] = await Promise.all([readFile(path.join(dataDir, rgb)), readFile(path.join(dataDir, depth))]);
    slam.pushFrame(c, d, Number(t));
  }
  const t0 = performance.now();
  const glb = slam.exportMesh({ format: 'glb' });
  const ms = performance.now() - t0;
  const report = await validate(glb, 'ICL mesh');
  assert.ok(report.info.totalTriangleCount > 50000, `${report.info.totalTriangleCount} triangles`);
  const points = await validate(slam.exportGlbPoints(), 'ICL points');
  assert.ok(points.info.totalVertexCount > 50000);
  console.log(`ICL-NUIM 10 frames: ${slam.surfelCount} surfels -> ${report.info.totalTriangleCount} triangles in ${ms.toFixed(0)} ms (wasm, 1 thread)`);
  slam.free();
});
