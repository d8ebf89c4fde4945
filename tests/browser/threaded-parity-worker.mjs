// Module worker of threaded-parity.test.mjs: loads the threaded module,
// starts its thread pool and plays the window sequence through Slam.pushRaw
// (a rayon pool blocks the thread that waits for it, which a page's main
// thread may not do, hence a worker, as www/worker.js).
self.onmessage = async ({ data: { modulePath, framesPath, input, threads } }) => {
  try {
    const m = await import(modulePath);
    await m.default({ module_or_path: new URL(modulePath.replace(/\.js$/, '_bg.wasm'), self.location.href) });
    await m.initThreadPool(threads);
    const response = await fetch(framesPath);
    if (!response.ok) throw new Error(`${framesPath}: HTTP ${response.status}`);
    const frames = new Uint8Array(await response.arrayBuffer());
    const { width, height, timestamps, config } = input;
    const pixels = width * height;
    if (frames.length !== timestamps.length * pixels * 6) {
      throw new Error(`${framesPath} has ${frames.length} bytes, not ${timestamps.length} frames of ${width}x${height}`);
    }
    const slam = new m.Slam(config);
    const poses = [];
    for (let i = 0; i < timestamps.length; i++) {
      const start = i * pixels * 6;
      const rgba = frames.subarray(start, start + 4 * pixels);
      const depth = new Uint16Array(frames.slice(start + 4 * pixels, start + 6 * pixels).buffer);
      const report = slam.pushRaw(width, height, rgba, depth, timestamps[i]);
      poses.push({ timestamp: report.timestamp, pose: Array.from(report.pose) });
    }
    postMessage({ ok: true, threads: m.threadCount(), poses });
    slam.free();
  } catch (e) {
    postMessage({ ok: false, error: e && e.stack ? e.stack : String(e) });
  }
};
