// The static server: cross-origin isolation headers, MIME types, no directory traversal.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import http from 'node:http';
import { startServer } from '../../www/serve.mjs';

function get(port, rawPath) {
  // http.get would normalise "..": send the path exactly as written.
  return new Promise((resolve, reject) => {
    const req = http.request({ host: '127.0.0.1', port, path: rawPath, method: 'GET' }, (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('end', () => resolve({ status: res.statusCode, headers: res.headers, body: Buffer.concat(chunks) }));
    });
    req.on('error', reject);
    req.end();
  });
}

test('serve.mjs: headers, MIME types and no directory traversal', async () => {
  const server = await startServer({ port: 0 });
  try {
    const index = await get(server.port, '/');
    assert.equal(index.status, 200);
    assert.match(index.headers['content-type'], /^text\/html/);
    assert.equal(index.headers['cross-origin-opener-policy'], 'same-origin');
    assert.equal(index.headers['cross-origin-embedder-policy'], 'require-corp');
    assert.equal(index.headers['cross-origin-resource-policy'], 'same-origin');

    const js = await get(server.port, '/app.js');
    assert.equal(js.status, 200);
    assert.match(js.headers['content-type'], /^text\/javascript/);
    const mjs = await get(server.port, '/serve.mjs');
    assert.match(mjs.headers['content-type'], /^text\/javascript/);
    const json = await get(server.port, '/sample/manifest.json');
    assert.match(json.headers['content-type'], /^application\/json/);
    const manifest = JSON.parse(json.body);
    const png = await get(server.port, `/sample/${manifest.files.find((f) => f.path.endsWith('.png')).path}`);
    assert.equal(png.headers['content-type'], 'image/png');
    assert.equal(png.headers['cross-origin-embedder-policy'], 'require-corp');

    const wasm = await get(server.port, '/pkg/surfel_slam_bg.wasm');
    if (wasm.status === 200) assert.equal(wasm.headers['content-type'], 'application/wasm');

    for (const p of ['/../package.json', '/%2e%2e/package.json', '/sample/..%2f..%2fpackage.json', '/..%5cpackage.json', '/%2e%2e%2f%2e%2e%2fetc/passwd']) {
      const r = await get(server.port, p);
      assert.ok(r.status === 403 || r.status === 404, `${p} -> ${r.status}`);
      assert.ok(!r.body.toString().includes('playwright-core'), `${p} leaked a file outside www/`);
    }
    assert.equal((await get(server.port, '/no-such-file.js')).status, 404);
  } finally {
    await server.close();
  }
});
