#!/usr/bin/python3
"""Independent reference for dcl::eval: ATE, RPE and the KITTI odometry metric.

Written from the definitions of the evo toolbox (MichaelGrupp/evo: sync.associate_trajectories,
geometry.umeyama_alignment, trajectory.align, metrics.APE / RPE, filters.filter_pairs_by_index)
and of the KITTI odometry devkit (evaluate_odometry.cpp: trajectoryDistances,
lastFrameFromSegmentLength, calcSequenceErrors), with numpy only and no code shared with the
C++ library, so that the two can check each other.

    reference_metrics.py ate|rpe --gt F --est F --format kitti|tum --align none|se3|sim3
                         [--delta N] [--max-diff S] [--offset S] [--orthonormalize]

prints one JSON object on stdout. Needs Debian's interpreter (/usr/bin/python3 with numpy).
Rotations are used as the files give them, as evo and the devkit do; --orthonormalize first
projects each onto SO(3) (nearest rotation in the Frobenius norm), as dcl::io's readers do.
KITTI rotations are orthonormal only to about 1e-7, which moves small-angle figures (RPE minima,
the KITTI rotation error) by up to about 1e-4 relative.
"""

import argparse
import json
import math
import sys

import numpy as np

KITTI_LENGTHS = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0]
KITTI_STEP = 10
# Second to first singular value of the cross-covariance below which Umeyama is degenerate.
DEGENERATE_RATIO = 1e-12


# ---------------------------------------------------------------------------------------------
# Files


def data_lines(path):
    with open(path, encoding="utf-8") as f:
        for line in f:
            text = line.strip()
            if text and not text.startswith("#"):
                yield text.replace(",", " ").split()


def read_kitti(path):
    """KITTI poses: 12 numbers a line, the row-major 3x4 [R|t]; stamps are the line indices."""
    poses = []
    for fields in data_lines(path):
        if len(fields) != 12:
            raise ValueError(f"{path}: expected 12 numbers a line, got {len(fields)}")
        pose = np.eye(4)
        pose[:3, :4] = np.array([float(x) for x in fields]).reshape(3, 4)
        poses.append(pose)
    return np.arange(len(poses), dtype=float), poses


def quaternion_to_matrix(x, y, z, w):
    q = np.array([w, x, y, z], dtype=float)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def read_tum(path):
    """TUM poses: 'stamp x y z qx qy qz qw' a line."""
    stamps, poses = [], []
    for fields in data_lines(path):
        if len(fields) != 8:
            raise ValueError(f"{path}: expected 8 numbers a line, got {len(fields)}")
        v = [float(x) for x in fields]
        pose = np.eye(4)
        pose[:3, 3] = v[1:4]
        pose[:3, :3] = quaternion_to_matrix(*v[4:8])
        stamps.append(v[0])
        poses.append(pose)
    return np.array(stamps), poses


# ---------------------------------------------------------------------------------------------
# Association


def associate_stamps(gt_stamps, est_stamps, max_diff, offset):
    """evo's associate_trajectories(gt, est): the shorter matched into the longer by np.argmin."""
    est_longer = len(est_stamps) > len(gt_stamps)
    short_stamps, long_stamps = (gt_stamps, est_stamps) if est_longer else (est_stamps, gt_stamps)
    shifted = np.array(long_stamps, dtype=float) + (offset if est_longer else -offset)
    short_ids, long_ids = [], []
    for i, t in enumerate(short_stamps):
        diffs = np.abs(shifted - t)
        j = int(np.argmin(diffs))
        if diffs[j] <= max_diff:
            short_ids.append(i)
            long_ids.append(j)
    if not short_ids:
        raise ValueError("no matching timestamps")
    # Returned as (ground-truth indices, estimate indices).
    return (short_ids, long_ids) if est_longer else (long_ids, short_ids)


def nearest_rotation(m):
    u, _, vt = np.linalg.svd(m)
    d = np.diag([1.0, 1.0, 1.0 if np.linalg.det(u @ vt) >= 0.0 else -1.0])
    return u @ d @ vt


def orthonormalized(poses):
    out = []
    for p in poses:
        q = p.copy()
        q[:3, :3] = nearest_rotation(p[:3, :3])
        out.append(q)
    return out


def load_pairs(args):
    reader = read_kitti if args.format == "kitti" else read_tum
    gt_stamps, gt_poses = reader(args.gt)
    est_stamps, est_poses = reader(args.est)
    if args.orthonormalize:
        gt_poses, est_poses = orthonormalized(gt_poses), orthonormalized(est_poses)
    if args.format == "kitti":
        if len(gt_poses) != len(est_poses):
            raise ValueError("KITTI files of different lengths")
        return gt_poses, est_poses
    gt_ids, est_ids = associate_stamps(gt_stamps, est_stamps, args.max_diff, args.offset)
    return [gt_poses[i] for i in gt_ids], [est_poses[i] for i in est_ids]


# ---------------------------------------------------------------------------------------------
# Geometry


def umeyama(x, y, with_scale):
    """Umeyama 1991 on 3xn point matrices: (r, t, c) minimising |y - (c r x + t)|^2."""
    n = x.shape[1]
    if n < 3:
        raise ValueError("Umeyama needs at least 3 points")
    mean_x = x.mean(axis=1)
    mean_y = y.mean(axis=1)
    xc = x - mean_x[:, None]
    yc = y - mean_y[:, None]
    sigma_x = np.sum(xc * xc) / n
    cov = yc @ xc.T / n
    u, d, vt = np.linalg.svd(cov)
    if not d[1] > DEGENERATE_RATIO * d[0]:
        raise ValueError("Umeyama: collinear or coincident points")
    s = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2] = -1.0
    r = u @ np.diag(s) @ vt
    c = float(np.dot(d, s) / sigma_x) if with_scale else 1.0
    t = mean_y - c * (r @ mean_x)
    return r, t, c


def align(gt_poses, est_poses, mode):
    """evo's trajectory.align: scale the estimate's positions by c, then left-multiply [r|t]."""
    if mode == "none":
        return est_poses, 1.0
    x = np.array([p[:3, 3] for p in est_poses]).T
    y = np.array([p[:3, 3] for p in gt_poses]).T
    r, t, c = umeyama(x, y, mode == "sim3")
    aligned = []
    for p in est_poses:
        q = np.eye(4)
        q[:3, :3] = r @ p[:3, :3]
        q[:3, 3] = c * (r @ p[:3, 3]) + t
        aligned.append(q)
    return aligned, c


def se3_inverse(p):
    inv = np.eye(4)
    inv[:3, :3] = p[:3, :3].T
    inv[:3, 3] = -p[:3, :3].T @ p[:3, 3]
    return inv


def rotation_angle(m):
    """The angle of scipy's Rotation.from_matrix(m).as_rotvec() (Markley's quaternion)."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    k = int(np.argmax([m[0, 0], m[1, 1], m[2, 2], trace]))
    q = np.zeros(4)  # x, y, z, w
    if k == 3:
        q[:] = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], 1.0 + trace]
    else:
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        q[i] = 1.0 - trace + 2.0 * m[i, i]
        q[j] = m[j, i] + m[i, j]
        q[l] = m[l, i] + m[i, l]
        q[3] = m[l, j] - m[j, l]
    q /= np.linalg.norm(q)
    if q[3] < 0.0:
        q = -q
    return 2.0 * math.atan2(np.linalg.norm(q[:3]), q[3])


# ---------------------------------------------------------------------------------------------
# Metrics


def statistics(errors):
    e = np.asarray(errors, dtype=float)
    return {
        "rmse": math.sqrt(np.mean(e ** 2)),
        "mean": float(np.mean(e)),
        "median": float(np.median(e)),
        "std": float(np.std(e)),
        "min": float(np.min(e)),
        "max": float(np.max(e)),
        "count": int(e.size),
    }


def ate(gt_poses, est_poses, mode):
    aligned, scale = align(gt_poses, est_poses, mode)
    t_err = [np.linalg.norm(p[:3, 3] - q[:3, 3]) for p, q in zip(aligned, gt_poses)]
    # evo's APE rotation: the angle of est^-1 gt.
    r_err = [math.degrees(rotation_angle((se3_inverse(p) @ q)[:3, :3]))
             for p, q in zip(aligned, gt_poses)]
    return {
        "metric": "ate", "align": mode, "pairs": len(gt_poses),
        "translation_m": statistics(t_err), "rotation_deg": statistics(r_err), "scale": scale,
    }


def index_pairs(n, delta):
    """evo's filter_pairs_by_index, consecutive pairs: 0, delta, 2 delta, ..."""
    ids = list(range(0, n, delta))
    return list(zip(ids, ids[1:]))


def kitti_metric(gt_poses, est_poses):
    """The devkit's calcSequenceErrors and its averages, in double precision."""
    steps = [np.linalg.norm(gt_poses[i][:3, 3] - gt_poses[i - 1][:3, 3])
             for i in range(1, len(gt_poses))]
    dist = [0.0]
    for s in steps:
        dist.append(dist[-1] + s)
    t_errs, r_errs = [], []
    for first in range(0, len(gt_poses), KITTI_STEP):
        for length in KITTI_LENGTHS:
            last = next((i for i in range(first, len(dist)) if dist[i] > dist[first] + length), -1)
            if last == -1:
                continue
            delta_gt = np.linalg.inv(gt_poses[first]) @ gt_poses[last]
            delta_est = np.linalg.inv(est_poses[first]) @ est_poses[last]
            error = np.linalg.inv(delta_est) @ delta_gt
            d = 0.5 * (error[0, 0] + error[1, 1] + error[2, 2] - 1.0)
            r_errs.append(math.acos(max(min(d, 1.0), -1.0)) / length)
            t_errs.append(np.linalg.norm(error[:3, 3]) / length)
    if not t_errs:
        return None
    return {
        "translation_percent": 100.0 * sum(t_errs) / len(t_errs),
        "rotation_deg_per_100m": 100.0 * math.degrees(sum(r_errs) / len(r_errs)),
        "segments": len(t_errs),
    }


def rpe(gt_poses, est_poses, mode, delta):
    aligned, _ = align(gt_poses, est_poses, mode)
    pairs = index_pairs(len(aligned), delta)
    if not pairs:
        raise ValueError(f"delta {delta} gives no pairs")
    t_err, r_err = [], []
    for i, j in pairs:
        q_rel = se3_inverse(gt_poses[i]) @ gt_poses[j]
        p_rel = se3_inverse(aligned[i]) @ aligned[j]
        e = se3_inverse(q_rel) @ p_rel
        t_err.append(np.linalg.norm(e[:3, 3]))
        r_err.append(math.degrees(rotation_angle(e[:3, :3])))
    return {
        "metric": "rpe", "delta": delta, "delta_unit": "frames", "align": mode,
        "pairs": len(pairs), "translation_m": statistics(t_err), "rotation_deg": statistics(r_err),
        "kitti": kitti_metric(gt_poses, aligned),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("metric", choices=["ate", "rpe"])
    parser.add_argument("--gt", required=True, help="ground-truth pose file")
    parser.add_argument("--est", required=True, help="estimated pose file")
    parser.add_argument("--format", choices=["kitti", "tum"], required=True)
    parser.add_argument("--align", choices=["none", "se3", "sim3"], default="none")
    parser.add_argument("--delta", type=int, default=1, help="RPE pair distance, frames")
    parser.add_argument("--max-diff", type=float, default=0.01, help="association tolerance, s")
    parser.add_argument("--offset", type=float, default=0.0, help="added to estimate stamps, s")
    parser.add_argument("--orthonormalize", action="store_true",
                        help="project rotations onto SO(3) first (as dcl::io's readers do)")
    args = parser.parse_args()
    if args.delta < 1:
        parser.error("--delta must be at least 1")
    try:
        gt_poses, est_poses = load_pairs(args)
        if args.metric == "ate":
            result = ate(gt_poses, est_poses, args.align)
        else:
            result = rpe(gt_poses, est_poses, args.align, args.delta)
    except ValueError as e:
        print(f"reference_metrics: {e}", file=sys.stderr)
        return 1
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
