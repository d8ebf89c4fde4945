"""Does a sequence's ground truth agree with its own depth images?

Issue #32 asks that every loop closure on the 7-Scenes kitchen move the pose
toward the ground truth. That truth is the dataset's own KinectFusion track
(no loop closure), so this script measures it against an independent
registration, Open3D's point-to-plane ICP between two depth frames started at
the pose being judged (0.02, 0.01, 0.005 m correspondence distances):

1. pairs 20 file frames apart (every 10th frame), and
2. revisits: pairs at least 200 file frames apart whose *estimated* poses lie
   within 30 cm and 15 degrees (chosen without the ground truth),

printing for each how far the registration moves the second camera's centre
when started at the ground truth's relative pose and at ours. Then
3. a pose graph: our tracked steps as odometry, the revisits' registrations
   as loop edges (Open3D's global optimisation), and ATE before and after at
   two odometry weights. A loop-consistent trajectory that scores a worse ATE
   says the ground truth cannot reward a correct closure.

`--tum` runs part 1 on a TUM folder (motion-capture truth) instead: the
registration's own spread, the floor of these numbers.

    scripts/check-ground-truth.sh <7-Scenes folder> <our trajectory (TUM format)>
    scripts/check-ground-truth.sh --tum <TUM folder>
"""

import glob
import os
import sys

import numpy as np
import open3d as o3d

REG = o3d.pipelines.registration


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def pose(v):
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(v[3:7])
    m[:3, 3] = v[0:3]
    return m


def load_tum_trajectory(path):
    rows = [[float(x) for x in line.split()] for line in open(path) if not line.startswith('#')]
    return [(r[0], pose(r[1:8])) for r in rows]


class Frames:
    """Depth frames as downsampled clouds with normals, camera frame, metres."""

    def __init__(self, intrinsics, depth_scale, path_of):
        self.k = o3d.camera.PinholeCameraIntrinsic(640, 480, *intrinsics)
        self.scale, self.path_of, self.cache = depth_scale, path_of, {}

    def cloud(self, key):
        if key not in self.cache:
            depth = o3d.io.read_image(self.path_of(key))
            pc = o3d.geometry.PointCloud.create_from_depth_image(
                depth, self.k, depth_scale=self.scale, depth_trunc=3.5).voxel_down_sample(0.01)
            pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=0.05, max_nn=30))
            self.cache[key] = pc
        return self.cache[key]

    def register(self, a, b, a_from_b):
        """ICP of frame b onto frame a from `a_from_b`; the result and its fitness at 1 cm."""
        t = a_from_b
        for d in [0.02, 0.01, 0.005]:
            t = REG.registration_icp(self.cloud(b), self.cloud(a), d, t,
                                     REG.TransformationEstimationPointToPlane(),
                                     REG.ICPConvergenceCriteria(max_iteration=50)).transformation
        fit = REG.evaluate_registration(self.cloud(b), self.cloud(a), 0.01, t).fitness
        return t, fit


def centre_moved_cm(a_from_b, registered):
    return 100 * np.linalg.norm(registered[:3, 3] - a_from_b[:3, 3])


def relative(poses, a, b):
    return np.linalg.inv(poses[a]) @ poses[b]


def judge(frames, pairs, truth, ours):
    """Per pair: how far registration moves b's centre from the truth's (and our) relative pose."""
    rows = []
    for a, b in pairs:
        row = []
        for poses in [truth] + ([ours] if ours else []):
            start = relative(poses, a, b)
            row.append(centre_moved_cm(start, frames.register(a, b, start)[0]))
        rows.append(row)
        print('  %4d -> %4d: registration moves the centre %s' % (a, b, described(row)), flush=True)
    print('  median: %s' % described(np.median(np.array(rows), 0)))


def described(row):
    return ', '.join('%5.2f cm from %s' % (v, who) for v, who in zip(row, ['the truth', 'ours']))


def ate_cm(poses, truth, keys):
    a = np.array([poses[k][:3, 3] for k in keys])
    b = np.array([truth[k][:3, 3] for k in keys])
    ma, mb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
    d = np.diag([1, 1, np.sign(np.linalg.det(vt.T @ u.T))])
    r = vt.T @ d @ u.T
    e = np.linalg.norm((r @ (a - ma).T).T + mb - b, axis=1)
    return 100 * np.sqrt((e ** 2).mean())


def revisits(ours, keys):
    """Pairs >= 200 file frames apart, within 30 cm and 15 degrees by our poses; one per 10 frames of b."""
    found = []
    for a in keys:
        for b in keys:
            if b - a < 200:
                continue
            r = relative(ours, a, b)
            dist = np.linalg.norm(r[:3, 3])
            angle = np.degrees(np.arccos(np.clip((np.trace(r[:3, :3]) - 1) / 2, -1, 1)))
            if dist < 0.3 and angle < 15:
                found.append((dist + 0.01 * angle, a, b))
    seen, pairs = set(), []
    for _, a, b in sorted(found):
        if b // 10 not in seen:
            seen.add(b // 10)
            pairs.append((a, b))
    return sorted(pairs, key=lambda p: p[1])


def pose_graph_ate(frames, ours, truth, keys, pairs, odometry_weight):
    graph = REG.PoseGraph()
    index = {k: i for i, k in enumerate(keys)}
    for k in keys:
        graph.nodes.append(REG.PoseGraphNode(ours[k]))
    for a, b in zip(keys, keys[1:]):
        graph.edges.append(REG.PoseGraphEdge(index[b], index[a], relative(ours, a, b),
                                             np.eye(6) * odometry_weight, uncertain=False))
    loops = 0
    for a, b in pairs:
        t, fit = frames.register(a, b, relative(ours, a, b))
        if fit < 0.3:
            continue
        info = REG.get_information_matrix_from_point_clouds(frames.cloud(b), frames.cloud(a), 0.01, t)
        graph.edges.append(REG.PoseGraphEdge(index[b], index[a], t, info, uncertain=True))
        loops += 1
    REG.global_optimization(graph, REG.GlobalOptimizationLevenbergMarquardt(),
                            REG.GlobalOptimizationConvergenceCriteria(),
                            REG.GlobalOptimizationOption(max_correspondence_distance=0.02,
                                                         edge_prune_threshold=0.25, reference_node=0))
    optimised = {k: graph.nodes[index[k]].pose for k in keys}
    return loops, ate_cm(optimised, truth, keys)


def seven_scenes(folder, trajectory):
    truth = {}
    for f in sorted(glob.glob(folder + '/frame-*.pose.txt')):
        truth[int(os.path.basename(f)[6:12])] = np.loadtxt(f)
    ours = {int(round(t)): m for t, m in load_tum_trajectory(trajectory)}
    keys = sorted(k for k in ours if k in truth)
    frames = Frames((585, 585, 320, 240), 1000.0, lambda k: '%s/frame-%06d.depth.png' % (folder, k))
    print('1. pairs 20 file frames apart')
    judge(frames, [(a, a + 20) for a in keys[::10] if a + 20 in ours], truth, ours)
    pairs = revisits(ours, keys)
    print('2. revisits (%d pairs, chosen by our poses)' % len(pairs))
    judge(frames, pairs, truth, ours)
    print('3. pose graph: our steps + the revisits registered; ATE as tracked %.3f cm' % ate_cm(ours, truth, keys))
    for w in [1e4, 1e6]:
        loops, ate = pose_graph_ate(frames, ours, truth, keys, pairs, w)
        print('  odometry weight %.0e, %d loop edges: ATE %.3f cm' % (w, loops, ate), flush=True)


def tum(folder):
    gt = np.array([[float(x) for x in line.split()] for line in open(folder + '/groundtruth.txt')
                   if not line.startswith('#')])
    depths = [line.split() for line in open(folder + '/depth.txt') if not line.startswith('#')]

    def truth_at(t):
        i = min(max(np.searchsorted(gt[:, 0], t), 1), len(gt) - 1)
        return pose(gt[i if abs(gt[i, 0] - t) < abs(gt[i - 1, 0] - t) else i - 1][1:8])

    truth = {i: truth_at(float(d[0])) for i, d in enumerate(depths)}
    frames = Frames((535.4, 539.2, 320.1, 247.6), 5000.0, lambda i: folder + '/' + depths[i][1])
    # Skip the frames recorded before the motion capture's first pose.
    start = int(np.searchsorted([float(d[0]) for d in depths], gt[0, 0]))
    print('1. pairs 10 frames apart, TUM motion-capture truth (the registration against itself)')
    pairs = [(a, a + 10) for a in range(start, len(depths) - 10, 10)]
    judge(frames, pairs, truth, None)


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == '--tum':
        tum(sys.argv[2])
    elif len(sys.argv) == 3:
        seven_scenes(sys.argv[1], sys.argv[2])
    else:
        sys.exit(__doc__)
