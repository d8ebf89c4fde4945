#!/usr/bin/env python3
"""Times Open3D's RGB-D odometry (hybrid Jacobian) on consecutive frame pairs
of a TUM or ICL-NUIM folder, for the side-by-side comparison in
scripts/compare-open3d.sh. Image loading is excluded from the timing; only
o3d.pipelines.odometry.compute_rgbd_odometry is timed.

usage: open3d_odometry.py <dataset dir> [--pairs N]
Last line: median_ms_per_pair: <number>
"""
import argparse
import os
import statistics
import sys
import time

import numpy
import open3d as o3d


def read_list(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                rows.append(line.split())
    return rows


def frame_pairs(folder):
    """(colour, depth) paths in sequence order, plus intrinsics and depth scale."""
    assoc = os.path.join(folder, "associations.txt")
    if os.path.exists(assoc):  # ICL-NUIM: "t depth t rgb"
        rows = read_list(assoc)
        frames = [(os.path.join(folder, r[3]), os.path.join(folder, r[1])) for r in rows]
        # Open3D takes fy > 0 (ICL-NUIM's own convention flips y with fy = -480).
        k = o3d.camera.PinholeCameraIntrinsic(640, 480, 481.2, 480.0, 319.5, 239.5)
        return frames, k, 5000.0
    rgb = [(float(r[0]), r[1]) for r in read_list(os.path.join(folder, "rgb.txt"))]
    depth = [(float(r[0]), r[1]) for r in read_list(os.path.join(folder, "depth.txt"))]
    frames, used = [], set()
    for t, name in rgb:  # TUM's associate.py rule: nearest depth within 0.02 s, used once
        best = min(depth, key=lambda d: abs(d[0] - t))
        if abs(best[0] - t) < 0.02 and best[1] not in used:
            used.add(best[1])
            frames.append((os.path.join(folder, name), os.path.join(folder, best[1])))
    k = o3d.camera.PinholeCameraIntrinsic(640, 480, 535.4, 539.2, 320.1, 247.6)  # fr3
    return frames, k, 5000.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dataset")
    ap.add_argument("--pairs", type=int, default=60)
    args = ap.parse_args()
    frames, k, scale = frame_pairs(args.dataset)
    frames = frames[: args.pairs + 1]
    images = []
    for c, d in frames:
        images.append(
            o3d.geometry.RGBDImage.create_from_color_and_depth(
                o3d.io.read_image(c), o3d.io.read_image(d), depth_scale=scale,
                depth_trunc=4.0, convert_rgb_to_intensity=True,
            )
        )
    option = o3d.pipelines.odometry.OdometryOption()
    jacobian = o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm()
    times, failed = [], 0
    for source, target in zip(images, images[1:]):
        t0 = time.perf_counter()
        ok, _, _ = o3d.pipelines.odometry.compute_rgbd_odometry(
            source, target, k, numpy.eye(4),
            jacobian, option,
        )
        times.append((time.perf_counter() - t0) * 1000.0)
        failed += 0 if ok else 1
    print(f"{args.dataset}: {len(times)} pairs, {failed} failed, Open3D {o3d.__version__}")
    print(f"median_ms_per_pair: {statistics.median(times):.2f}")


if __name__ == "__main__":
    sys.exit(main())
