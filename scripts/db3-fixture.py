#!/usr/bin/env python3
"""Makes tests/data/realsense_teddy_crop.db3: TUM fr3 teddy's depth frames FIRST..FIRST+COUNT
(and their associated colour), cropped to the 320x240 centre of the 640x480 images, written as a
RealSense ROS2 bag by librealsense's own recorder (/work/shared/tools/write-realsense-recording.py,
pyrealsense2 >= 2.58). Cropping (not resizing) keeps every pixel exactly a TUM pixel, so the test
compares the decoded frames with the TUM PNGs byte for byte; the crop moves the principal point by
the crop's corner.

usage: V/bin/python scripts/db3-fixture.py TUM_DIR OUT.db3 [FIRST COUNT]
needs: python3 -m venv V && V/bin/pip install numpy pillow pyrealsense2
"""
import os, subprocess, sys, tempfile
from PIL import Image

X, Y, W, H = 160, 120, 320, 240
src, out = sys.argv[1], sys.argv[2]
first, count = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) > 4 else (4, 8)
tool = "/work/shared/tools/write-realsense-recording.py"
with tempfile.TemporaryDirectory() as tmp:
    for index in ("rgb.txt", "depth.txt"):
        rows = [l.split() for l in open(os.path.join(src, index)) if l.strip() and not l.startswith("#")]
        with open(os.path.join(tmp, index), "w") as f:
            for t, name in rows:
                # Only the images the tool can reach (association picks within 0.02 s).
                os.makedirs(os.path.join(tmp, os.path.dirname(name)), exist_ok=True)
                f.write(f"{t} {name}\n")
                Image.open(os.path.join(src, name)).crop((X, Y, X + W, Y + H)).save(os.path.join(tmp, name))
    fx, fy, cx, cy = 535.4, 539.2, 320.1 - X, 247.6 - Y
    subprocess.run([sys.executable, tool, tmp, out, "--intrinsics", str(fx), str(fy), str(cx), str(cy),
                    "--first", str(first), "--count", str(count)], check=True)
