"""End-to-end tests of the dcl-slam command, run as a user runs it.

The metrics are compared with tests/eval/reference_metrics.py, an
independent numpy implementation of evo's definitions.
"""
import csv
import json
import math
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

DCL_SLAM = os.environ["DCL_SLAM"]
DATA = os.environ["DCL_DATA_DIR"]
SOURCE = os.environ["DCL_SOURCE_DIR"]
EVO = os.path.join(DATA, "trajectories", "evo")
REFERENCE = os.path.join(SOURCE, "tests", "eval", "reference_metrics.py")


def run(*args, check=True):
    """Runs dcl-slam with args; returns (exit code, stdout, stderr)."""
    proc = subprocess.run([DCL_SLAM, *args], capture_output=True, text=True, timeout=300)
    if check and proc.returncode != 0:
        raise AssertionError(f"dcl-slam {' '.join(args)} failed: {proc.stderr}")
    return proc.returncode, proc.stdout, proc.stderr


def reference(*args):
    proc = subprocess.run([sys.executable, REFERENCE, *args], capture_output=True, text=True,
                          timeout=300, check=True)
    return json.loads(proc.stdout)


def leaves(value, prefix=""):
    """Flattens nested JSON into {"a.b": leaf}."""
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            out.update(leaves(item, f"{prefix}{key}."))
        return out
    return {prefix.rstrip("."): value}


class Metrics(unittest.TestCase):
    """dcl-slam eval against the independent reference, to 1e-6 relative."""

    def assertMatchesReference(self, ours, ref):
        ours, ref = leaves(ours), leaves(ref)
        self.assertEqual(set(ref) - set(ours), set(), "fields missing from dcl-slam's JSON")
        for key, expected in ref.items():
            got = ours[key]
            if isinstance(expected, (int, float)) and not isinstance(expected, bool):
                tolerance = 1e-6 * max(abs(expected), 1e-12)
                self.assertLessEqual(abs(got - expected), tolerance,
                                     f"{key}: dcl-slam {got!r}, reference {expected!r}")
            else:
                self.assertEqual(got, expected, key)

    def test_ate_kitti00_orb_all_alignments(self):
        for align in ("sim3", "se3", "none"):
            with self.subTest(align=align):
                args = ["--gt", os.path.join(EVO, "KITTI_00_gt.txt"),
                        "--est", os.path.join(EVO, "KITTI_00_ORB.txt"),
                        "--format", "kitti", "--align", align]
                _, out, _ = run("eval", "ate", *args, "--json")
                ours = json.loads(out)
                self.assertEqual(ours["translation_m"]["count"], 4541)
                self.assertMatchesReference(ours, reference("ate", *args))

    def test_rpe_kitti00_sptam(self):
        args = ["--gt", os.path.join(EVO, "KITTI_00_gt.txt"),
                "--est", os.path.join(EVO, "KITTI_00_SPTAM.txt"),
                "--format", "kitti", "--align", "none", "--delta", "1"]
        _, out, _ = run("eval", "rpe", *args, "--json")
        ours = json.loads(out)
        self.assertIsNotNone(ours["kitti"])
        self.assertMatchesReference(ours, reference("rpe", *args))

    def test_ate_tum_association(self):
        args = ["--gt", os.path.join(EVO, "freiburg1_xyz-groundtruth.txt"),
                "--est", os.path.join(EVO, "freiburg1_xyz-rgbdslam.txt"),
                "--format", "tum", "--align", "se3"]
        _, out, _ = run("eval", "ate", *args, "--json")
        self.assertMatchesReference(json.loads(out), reference("ate", *args))

    def test_multi_robot_protocol_one_alignment_for_all(self):
        """KITTI 00 split into three robots; the alignment fitted on robot 1 serves all."""
        sys.path.insert(0, os.path.dirname(REFERENCE))
        import numpy as np
        import reference_metrics as ref
        _, gt = ref.read_kitti(os.path.join(EVO, "KITTI_00_gt.txt"))
        _, est = ref.read_kitti(os.path.join(EVO, "KITTI_00_ORB.txt"))
        cuts = [(0, 1500), (1500, 3000), (3000, len(gt))]
        with tempfile.TemporaryDirectory() as tmp:
            args = []
            for i, (a, b) in enumerate(cuts):
                for name, poses in (("gt", gt), ("est", est)):
                    path = os.path.join(tmp, f"{name}{i}.txt")
                    with open(path, "w") as f:
                        for p in poses[a:b]:
                            f.write(" ".join(repr(v) for v in p[:3, :].reshape(-1)) + "\n")
                    args += [f"--{name}", path]
            _, out, _ = run("eval", "ate", *args, "--format", "kitti", "--align", "se3",
                            "--reference-robot", "1", "--json")
        ours = json.loads(out)
        a, b = cuts[1]
        x = np.array([p[:3, 3] for p in est[a:b]]).T
        y = np.array([p[:3, 3] for p in gt[a:b]]).T
        r, t, _ = ref.umeyama(x, y, False)
        all_errors = []
        for i, (a, b) in enumerate(cuts):
            errors = [np.linalg.norm(r @ e[:3, 3] + t - g[:3, 3])
                      for e, g in zip(est[a:b], gt[a:b])]
            all_errors += errors
            expected = ref.statistics(errors)["rmse"]
            got = ours["robots"][i]["translation_m"]["rmse"]
            self.assertAlmostEqual(got / expected, 1.0, delta=1e-6, msg=f"robot {i}")
        pooled = ref.statistics(all_errors)
        self.assertEqual(ours["pooled"]["translation_m"]["count"], len(gt))
        self.assertAlmostEqual(ours["pooled"]["translation_m"]["rmse"] / pooled["rmse"], 1.0,
                               delta=1e-6)
        self.assertEqual(ours["reference_robot"], 1)

    def test_human_readable_table(self):
        _, out, _ = run("eval", "ate", "--gt", os.path.join(EVO, "KITTI_00_gt.txt"),
                        "--est", os.path.join(EVO, "KITTI_00_ORB.txt"), "--format", "kitti",
                        "--align", "sim3")
        self.assertIn("4541 pose pairs", out)
        self.assertIn("trans [m]", out)


class Convert(unittest.TestCase):
    """dcl-slam convert: formats round-trip through the command."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def path(self, name):
        return os.path.join(self.dir, name)

    def test_scan_round_trip_through_pcd_and_ply(self):
        scan = os.path.join(DATA, "lidar_scans", "kitti_00", "velodyne", "000000.bin")
        run("convert", scan, self.path("a.pcd"), "--encoding", "ascii")
        run("convert", self.path("a.pcd"), self.path("b.ply"))
        run("convert", self.path("b.ply"), self.path("c.bin"))
        with open(scan, "rb") as a, open(self.path("c.bin"), "rb") as c:
            self.assertEqual(a.read(), c.read(), "KITTI scan changed through PCD and PLY")

    def test_poses_round_trip_kitti_tum_kitti(self):
        gt = os.path.join(EVO, "KITTI_00_gt.txt")
        times = os.path.join(EVO, "KITTI_00_gt_times.txt")
        run("convert", gt, self.path("gt.tum"), "--from", "kitti", "--to", "tum", "--times", times)
        run("convert", self.path("gt.tum"), self.path("gt.kitti"), "--from", "tum", "--to", "kitti")
        _, out, _ = run("eval", "ate", "--gt", gt, "--est", self.path("gt.kitti"), "--format",
                        "kitti", "--json")
        result = json.loads(out)
        self.assertEqual(result["translation_m"]["count"], 4541)
        self.assertLess(result["translation_m"]["max"], 1e-6)
        self.assertLess(result["rotation_deg"]["max"], 1e-4)

    def test_bag_pose_topic_to_tum(self):
        bag = os.path.join(DATA, "rosbags", "evo_ROS_example.bag")
        _, out, _ = run("convert", bag, self.path("gt.tum"), "--topic", "/groundtruth")
        with open(self.path("gt.tum")) as f:
            lines = [l for l in f if l.strip() and not l.startswith("#")]
        self.assertGreater(len(lines), 100)
        self.assertEqual(len(lines[0].split()), 8)

    def make_bag(self):
        script = os.path.join(SOURCE, "tests", "io", "make_test_bag.py")
        subprocess.run(["/usr/bin/python3", script, self.dir], check=True, timeout=120)
        return self.path("clouds.bag")

    def test_bag_clouds_to_scan_folder(self):
        bag = self.make_bag()
        run("convert", bag, self.path("scans"), "--topic", "/velodyne_points",
            "--cloud-format", "pcd", "--encoding", "ascii")
        names = sorted(os.listdir(self.path("scans")))
        self.assertEqual(names, [".dcl-slam", "000000.pcd", "000001.pcd", "000002.pcd", "times.txt"])
        with open(self.path("scans/times.txt")) as f:
            self.assertEqual(len(f.read().split()), 3)
        with open(self.path("scans/000000.pcd")) as f:
            header = f.read()
        self.assertIn("FIELDS x y z intensity", header)
        self.assertIn("DATA ascii", header)

    def test_bag_odometry_to_kitti(self):
        bag = self.make_bag()
        run("convert", bag, self.path("odom.txt"), "--topic", "/odom", "--to", "kitti")
        with open(self.path("odom.txt")) as f:
            rows = [list(map(float, l.split())) for l in f if l.strip()]
        self.assertEqual(len(rows), 3)
        self.assertAlmostEqual(rows[2][3], 2.0)   # x of pose k = 2
        self.assertAlmostEqual(rows[2][7], 4.0)   # y = 2k

    def test_bag_without_topic_lists_topics(self):
        bag = os.path.join(DATA, "rosbags", "evo_ROS_example.bag")
        code, _, err = run("convert", bag, self.path("x.tum"), check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("groundtruth", err)
        self.assertIn("geometry_msgs/PoseStamped", err)


class Config(unittest.TestCase):
    """dcl-slam config --dump: complete, commented, and it loads back."""

    def dump_with(self, yaml_text):
        """Runs `config --dump --config FILE` on `yaml_text`; returns (code, out, err, path)."""
        with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
            f.write(yaml_text)
        try:
            return (*run("config", "--dump", "--config", f.name, check=False), f.name)
        finally:
            os.unlink(f.name)

    def test_dump_loads_back_to_the_same_configuration(self):
        _, dump, _ = run("config", "--dump")
        self.assertIn("max_time_diff", dump)
        self.assertIn("#", dump)
        changed = dump.replace("max_time_diff: 0.01", "max_time_diff: 0.25")
        code, again, _, _ = self.dump_with(changed)
        self.assertEqual(code, 0)
        self.assertIn("max_time_diff: 0.25", again)
        self.assertEqual(changed, again)

    def test_unknown_key_is_named(self):
        code, _, err, path = self.dump_with("eval:\n  max_time_dif: 0.2\n")
        self.assertNotEqual(code, 0)
        self.assertIn("max_time_dif", err)
        self.assertIn(path, err)

    def test_wrong_type_is_named(self):
        code, _, err, _ = self.dump_with("eval:\n  kitti_step: ten\n")
        self.assertNotEqual(code, 0)
        self.assertIn("eval.kitti_step", err)

    def test_value_outside_its_set_is_named(self):
        code, _, err, path = self.dump_with("eval:\n  alignment: affine\n")
        self.assertNotEqual(code, 0)
        self.assertIn("eval.alignment", err)
        self.assertIn("affine", err)
        self.assertIn(path, err)

    def test_bad_values_are_refused_naming_file_line_field_rule_and_value(self):
        # (document, line, dotted key, rule and value as the message gives them)
        cases = [
            ("# a comment\nplace:\n  descriptor:\n    iris:\n      rows: 0\n", 5,
             "place.descriptor.iris.rows", "must be in [1, 1024], found 0"),
            ("place:\n  descriptor:\n    kind: sift\n", 3, "place.descriptor.kind",
             'must be one of iris, scancontext, found "sift"'),
            ("odometry:\n  min_range: 130\n  max_range: 120\n", 2, "odometry.min_range",
             "must be less than max_range (120), found 130"),
            ("odometry:\n  max_range: 1.5\n", 2, "odometry.min_range",
             "found 2 (the default; max_range is set on line 2)"),
            ("mapper:\n  solver:\n    threads: -4\n", 3, "mapper.solver.threads",
             "must be in [1, 256], found -4"),
            ("verification:\n  ransac:\n    confidence: 1.5\n", 3,
             "verification.ransac.confidence", "must be in (0, 1), found 1.5"),
            ("external:\n  T_body_sensor: [0, 0, 0, 0, 0, 0, 0]\n", 2, "external.T_body_sensor",
             "unit quaternion"),
        ]
        for yaml_text, line, key, what in cases:
            with self.subTest(key=key):
                code, out, err, path = self.dump_with(yaml_text)
                self.assertNotEqual(code, 0)
                self.assertEqual(out, "")
                lines = err.splitlines()
                self.assertEqual(len(lines), 1, err)
                self.assertTrue(
                    lines[0].startswith(f"dcl-slam: error: {path}:{line}: field '{key}': "), err)
                self.assertIn(what, lines[0])

    def test_every_command_taking_a_config_refuses_it_before_it_starts(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "bad.yaml")
            with open(path, "w") as f:
                f.write("mapper:\n  solver:\n    loop_loss: squiggle\n")
            for args in (["run", "--dataset", tmp, "--out", tmp], ["eval", "ate", "--gt", path,
                         "--est", path], ["version"]):
                with self.subTest(command=args[0]):
                    code, _, err = run(*args, "--config", path, check=False)
                    self.assertNotEqual(code, 0)
                    self.assertTrue(err.startswith(
                        f"dcl-slam: error: {path}:3: field 'mapper.solver.loop_loss': must be "
                        'one of none, huber, cauchy, found "squiggle"'), err)


class Demo(unittest.TestCase):
    """dcl-slam demo: no arguments but an output folder; simulates the demo
    swarm, runs it over the simulated radio and writes every output."""

    @staticmethod
    def read_coloured_ply(path):
        """The vertices of a binary PLY map written by dcl-slam: [(x, y, z)] and
        [(red, green, blue)]; fails unless the header is exactly that layout and
        the data exactly that long."""
        import struct
        with open(path, "rb") as f:
            data = f.read()
        end = data.index(b"end_header\n") + len(b"end_header\n")
        header = data[:end].decode("ascii").splitlines()
        assert header[:2] == ["ply", "format binary_little_endian 1.0"], header[:2]
        count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
        properties = [line.split()[1:] for line in header if line.startswith("property")]
        assert properties == [["float", "x"], ["float", "y"], ["float", "z"], ["uchar", "red"],
                              ["uchar", "green"], ["uchar", "blue"]], properties
        assert len(data) - end == 15 * count, (len(data) - end, count)
        records = list(struct.iter_unpack("<3f3B", data[end:]))
        return [r[:3] for r in records], [r[3:] for r in records]

    @staticmethod
    def report_colours(path):
        """Each robot's colour in report.html's legend: {name: (r, g, b)}."""
        with open(path) as f:
            html = f.read()
        found = re.findall(r'class="swatch" style="background:#([0-9a-f]{6})"></span>([^<]+)<',
                           html)
        return {name: tuple(bytes.fromhex(hex_colour)) for hex_colour, name in found}

    @staticmethod
    def check_maps(test, out, metrics):
        """map.ply and every robot's map.ply: valid, sized as metrics.json says,
        each robot in its report.html colour, and the merged map holding all."""
        import math
        colours = Demo.report_colours(os.path.join(out, "report.html"))
        names = [r["name"] for r in metrics["robots"]]
        test.assertEqual(sorted(colours), sorted(names))
        test.assertEqual(len(set(colours.values())), len(names))
        for r in metrics["robots"]:
            points, robot_colours = Demo.read_coloured_ply(os.path.join(out, r["name"], "map.ply"))
            test.assertEqual(len(points), r["map_points"], r["name"])
            test.assertGreater(len(points), 1000, r["name"])
            test.assertEqual(set(robot_colours), {colours[r["name"]]}, r["name"])
        points, merged_colours = Demo.read_coloured_ply(os.path.join(out, "map.ply"))
        test.assertEqual(len(points), metrics["map_points"])
        test.assertEqual(set(merged_colours), set(colours.values()))
        # Voxel-filtered: where robots overlap they share points, so the merged map is
        # smaller than its parts, and no two of its points fall in one voxel.
        test.assertLess(len(points), sum(r["map_points"] for r in metrics["robots"]))
        voxel = metrics["map_voxel_m"]
        cells = {tuple(math.floor(c / voxel) for c in p) for p in points}
        test.assertEqual(len(cells), len(points))
        return points

    def check_bound(self, out, metrics):
        """bench bound on the demo's outputs: the run and the odometry as the run's
        metrics have them, beside the joint graph's optimum and exact loops."""
        dataset = os.path.join(out, "dataset")
        _, stdout, _ = run("bench", "bound", "--run", out, "--dataset", dataset, "--json")
        bound = json.loads(stdout)
        self.assertEqual([r["name"] for r in bound["robots"]], ["a", "b", "c"])
        for b, m in zip(bound["robots"], metrics["robots"]):
            self.assertAlmostEqual(b["ate_run"], m["ate_rmse"], delta=1e-6)
            self.assertAlmostEqual(b["ate_odometry"], m["ate_rmse_odometry_only"],
                                   delta=1e-3 * m["ate_rmse_odometry_only"])
            # One alignment for all robots, as the run's report fits it.
            self.assertAlmostEqual(b["ate_joint_run"], m["ate_rmse_joint"], delta=1e-6)
            for key in ("ate_own_loops", "ate_optimum", "ate_exact", "ate_joint_optimum",
                        "ate_joint_exact"):
                self.assertGreater(b[key], 0.0, key)
                self.assertLess(b[key], 0.5, key)
            # Aligned with the others a robot can only lose against its own alignment.
            for key in ("run", "optimum", "exact"):
                self.assertGreaterEqual(b["ate_joint_" + key], b["ate_" + key] - 1e-9, key)
        for key in ("own_loops", "run", "optimum", "exact"):
            self.assertIn("mean_ate_lowered", bound["lowered"][key])
        # Solved from the run's estimates, the optimum costs no more than they do.
        self.assertGreater(bound["cost_optimum"], 0.0)
        self.assertLessEqual(bound["cost_optimum"], bound["cost_run"] * (1.0 + 1e-9))
        # No robot left: no figures without them.
        self.assertEqual(bound["left"], [])
        self.assertFalse(any(r["left"] for r in bound["robots"]))
        self.assertEqual(bound["cost_run_stayed"], 0.0)
        # A run of another dataset is named, with the robot it lacks.
        other = os.path.join(out, "other")
        os.makedirs(os.path.join(other, "a"))
        code, _, err = run("bench", "bound", "--run", other, "--dataset", dataset, check=False)
        self.assertEqual(code, 1)
        self.assertIn("graph.g2o", err)
        self.assertIn("'a'", err)

    def check_noise(self, out):
        """bench noise on the demo's outputs against the same figures computed here
        from graph.g2o, trajectory.tum and the ground truth: keyframe odometry,
        own and inter-robot loops; compounded odometry's covariance grows with
        its span."""
        import numpy as np
        dataset = os.path.join(out, "dataset")
        _, stdout, _ = run("bench", "noise", "--run", out, "--dataset", dataset, "--json")
        rows = {r["factors"]: r for r in json.loads(stdout)["factors"]}

        def pose(v):
            x, y, z, w = v[3:7]
            n = np.sqrt(x * x + y * y + z * z + w * w)
            x, y, z, w = x / n, y / n, z / n, w / n
            T = np.eye(4)
            T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
            T[:3, 3] = v[:3]
            return T

        def hat(w):
            return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])

        def log(T):  # [rho; phi], rho = J_l(phi)^-1 t
            R = T[:3, :3]
            angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
            axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
            phi = axis if angle < 1e-12 else axis * angle / np.sin(angle)
            if angle < 1e-6:
                J_inv = np.eye(3) - hat(phi) / 2
            else:
                J_inv = (np.eye(3) - hat(phi) / 2 + (1 / angle ** 2 - (1 + np.cos(angle)) /
                         (2 * angle * np.sin(angle))) * hat(phi) @ hat(phi))
            return np.concatenate([J_inv @ T[:3, 3], phi])

        names = ["a", "b", "c"]
        truth = {}
        for r in names:
            gt = {}
            with open(os.path.join(dataset, "ground_truth", r + ".tum")) as f:
                for line in f:
                    v = line.split()
                    if len(v) == 8:
                        gt[round(float(v[0]), 6)] = pose([float(x) for x in v[1:]])
            with open(os.path.join(out, r, "trajectory.tum")) as f:
                truth[r] = [gt[round(float(line.split()[0]), 6)] for line in f if line.strip()]
        sums = {"odometry": [], "own": [], "inter": []}
        seen = set()
        for r in names:
            with open(os.path.join(out, r, "graph.g2o")) as f:
                for line in f:
                    v = line.split()
                    if v[0] != "EDGE_SE3:QUAT":
                        continue
                    ends = [(chr(int(k) >> 56), int(k) & ((1 << 56) - 1)) for k in v[1:3]]
                    (ra, i), (rb, j) = ends
                    if ra == rb and ra != r or tuple(sorted(ends)) in seen:
                        continue
                    seen.add(tuple(sorted(ends)))
                    kind = "inter" if ra != rb else ("odometry" if j == i + 1 else "own")
                    info = np.zeros((6, 6))
                    info[np.triu_indices(6)] = [float(x) for x in v[10:31]]
                    info = info + np.triu(info, 1).T
                    Z = pose([float(x) for x in v[3:10]])
                    e = log(np.linalg.inv(Z) @ np.linalg.inv(truth[ra][i]) @ truth[rb][j])
                    C = np.linalg.inv(info)
                    sums[kind].append((e[:3] @ e[:3], np.trace(C[:3, :3]), e[3:] @ e[3:],
                                       np.trace(C[3:, 3:]), e @ info @ e, *(e * e), *np.diag(C)))
        for kind, key in (("odometry", "odometry, 1 keyframe"), ("own", "own loops"),
                          ("inter", "inter-robot loops")):
            row, mine = rows[key], np.array(sums[kind])
            self.assertEqual(row["count"], len(mine), key)
            self.assertGreater(len(mine), 0, key)
            mean = mine.mean(axis=0)
            for field, value in (("error_t_m", np.sqrt(mean[0])), ("sigma_t_m", np.sqrt(mean[1])),
                                 ("error_r_rad", np.sqrt(mean[2])),
                                 ("sigma_r_rad", np.sqrt(mean[3])), ("nees_per_dof", mean[4] / 6)):
                self.assertAlmostEqual(row[field], value, delta=1e-6 * value, msg=key + field)
            for k in range(6):  # per axis: x y z, roll pitch yaw
                for field, value in (("error_axes", np.sqrt(mean[5 + k])),
                                     ("sigma_axes", np.sqrt(mean[11 + k]))):
                    self.assertAlmostEqual(row[field][k], value, delta=1e-6 * value + 1e-12,
                                           msg=f"{key} {field}[{k}]")
        one, ten = rows["odometry, 1 keyframe"], rows["odometry, 10 keyframes"]
        self.assertGreater(ten["count"], 0)
        self.assertGreater(ten["sigma_t_m"], 2 * one["sigma_t_m"])
        self.assertGreater(ten["sigma_r_rad"], 2 * one["sigma_r_rad"])

    def test_demo_runs_the_swarm_and_writes_its_outputs(self):
        with tempfile.TemporaryDirectory() as tmp:
            _, out, _ = run("demo", "--out", tmp)
            with open(os.path.join(tmp, "metrics.json")) as f:
                metrics = json.load(f)
            robots = metrics["robots"]
            self.assertEqual([r["name"] for r in robots], ["a", "b", "c"])
            for r in robots:
                self.assertGreater(r["frames"], 900)
                self.assertLess(r["ate_rmse"], 0.5, r["name"])
                self.assertLess(r["ate_rmse_odometry_only"], 0.5, r["name"])
                self.assertGreater(r["bytes_sent"], 0, r["name"])
                # What the demo shows: collaboration takes a good part of every
                # car's drift out (34-91 % in five worlds, with traffic and
                # without; BENCHMARKS.md, "The demo").
                self.assertLess(r["ate_rmse"], 0.8 * r["ate_rmse_odometry_only"], r["name"])
            # The cars' loops share streets: robots find, verify and keep loops with each other.
            self.assertGreater(sum(r["inter_loops_accepted"] for r in robots), 20)
            self.assertGreater(metrics["robots"][1]["inter_loops_accepted"], 20)
            # Every robot took part in a finished optimisation round: one frame for all.
            for r in robots:
                self.assertGreater(r["counters"].get("dgs_rounds", 0), 0, r["name"])
                self.assertEqual(r["frame"], "a", r["name"])
                self.assertLess(r["ate_rmse_joint"], 0.5, r["name"])
            for name in ("report.html", "preview_world.png", "dataset/dataset.yaml",
                         "a/trajectory.tum", "b/graph.g2o", "c/odometry.tum"):
                self.assertTrue(os.path.exists(os.path.join(tmp, name)), name)
            # The merged map: every robot's points in its report colour.
            points = self.check_maps(self, tmp, metrics)
            self.assertGreater(len(points), 10000)
            self.check_bound(tmp, metrics)
            self.check_noise(tmp)
        self.assertIn("ATE collab", out)
        # The cut per robot, in percent, as the metrics give it.
        for r in metrics["robots"]:
            row = next(line.split() for line in out.splitlines()
                       if line.split()[:1] == [r["name"]])
            cut = 100 * (1 - r["ate_rmse"] / r["ate_rmse_odometry_only"])
            self.assertEqual(row[3:5], [f"{cut:.0f}", "%"], row)
        self.assertIn("map.ply", out)
        self.assertLess(len(out.splitlines()), 12)


class DemoDataset(unittest.TestCase):
    """A simulated small-3 dataset (ground truth only, scans regenerated), shared by a class."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "demo")
        run("simulate", "--preset", "small-3", "--out", cls.dataset)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()


class Odometry(DemoDataset):
    """dcl-slam odometry: one robot of a simulated dataset, built-in and external front-ends."""

    def run_odometry(self, name, *extra):
        out = os.path.join(self.tmp.name, name)
        _, stdout, _ = run("odometry", "--dataset", self.dataset, "--robot", "b", "--out", out,
                           "--max-frames", "200", *extra)
        with open(os.path.join(out, "metrics.json")) as f:
            return out, stdout, json.load(f)

    def test_lidar_odometry_tracks_the_ground_truth(self):
        out, stdout, metrics = self.run_odometry("lidar")
        self.assertEqual(metrics["odometry"], "lidar")
        self.assertEqual(metrics["frames"]["frames"], 200)
        self.assertEqual(metrics["frames"]["accepted"], 200)
        self.assertGreater(metrics["frames"]["distance_m"], 20.0)
        # 20 s of VLP-16 driving in the small-3 campus: centimetres, not decimetres.
        self.assertLess(metrics["accuracy"]["odometry"]["ate_se3_translation_m"]["rmse"], 0.10)
        self.assertGreater(metrics["mapper"]["keyframes"], 10)
        for name in ("trajectory.tum", "trajectory.kitti", "times.txt", "odometry.tum",
                     "keyframes/poses.tum", "keyframes/graph.g2o", "keyframes/000000.bin"):
            self.assertTrue(os.path.exists(os.path.join(out, name)), name)
        self.assertIn("keyframes", stdout)

    def test_bench_odometry_says_whether_the_imu_levelled_it(self):
        # The small-3 robots read up from their IMU with every scan.
        args = ("bench", "odometry", "--dataset", self.dataset, "--robot", "a",
                "--max-frames", "30")
        _, stdout, _ = run(*args, "--json")
        self.assertEqual(json.loads(stdout)["imu_readings_used"], 30)
        config = os.path.join(self.tmp.name, "lidar_only.yaml")
        with open(config, "w") as f:
            f.write("odometry: {use_imu: false}\n")
        _, stdout, _ = run("--config", config, *args)
        self.assertIn("LiDAR only", stdout)
        _, stdout, _ = run(*args)
        self.assertIn("levelled with the IMU at 30 frames", stdout)

    def test_external_odometry_replays_a_pose_file(self):
        gt = os.path.join(self.dataset, "ground_truth", "b.tum")
        _, _, metrics = self.run_odometry("external", "--external", gt)
        self.assertEqual(metrics["odometry"], "external")
        self.assertLess(metrics["accuracy"]["odometry"]["ate_se3_translation_m"]["rmse"], 1e-6)

    def test_a_robot_still_standing_gets_its_outputs_and_no_ate(self):
        # Robot c of small-3 stands for its first seconds: its ground truth is one
        # point, which no alignment can fit. The run is still written, and says why.
        out = os.path.join(self.tmp.name, "standing")
        _, stdout, _ = run("odometry", "--dataset", self.dataset, "--robot", "c", "--out", out,
                           "--max-frames", "20")
        with open(os.path.join(out, "metrics.json")) as f:
            metrics = json.load(f)
        self.assertEqual(metrics["frames"]["frames"], 20)
        self.assertIn("collinear or coincident", metrics["accuracy"]["odometry"]["unavailable"])
        self.assertIn("no ATE", stdout)
        for name in ("trajectory.tum", "odometry.tum", "keyframes/poses.tum"):
            self.assertTrue(os.path.exists(os.path.join(out, name)), name)

    def test_external_poses_on_another_clock_are_refused_before_anything_is_written(self):
        # The ground truth in Unix time against scans stamped from the robot's start.
        external = os.path.join(self.tmp.name, "unix_time.tum")
        with open(os.path.join(self.dataset, "ground_truth", "b.tum")) as f, \
                open(external, "w") as out:
            for line in f:
                t, rest = line.split(" ", 1)
                out.write(f"{float(t) + 1.7e9!r} {rest}")
        out = os.path.join(self.tmp.name, "unix_time")
        code, _, err = run("odometry", "--dataset", self.dataset, "--robot", "b", "--out", out,
                           "--max-frames", "20", "--external", external, check=False)
        self.assertEqual(code, 1)
        self.assertEqual(len(err.strip().splitlines()), 1, err)
        self.assertRegex(err, r"external odometry: its poses span 17\d{8}\.\d+ \.\. 17\d{8}\.\d+ s, "
                              r"the scans 0\.\d+ \.\. 1\.\d+ s")
        self.assertFalse(os.path.exists(out))

    def test_kitti_times_that_do_not_increase_are_refused_before_anything_is_written(self):
        folder = os.path.join(self.tmp.name, "kitti")
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, "dataset.yaml"), "w") as f:
            f.write("format_version: 1\nname: kitti00\nsensor:\n  model: hdl64\n"
                    "  mount_height: 1.73\nrobots:\n  - name: a\n    scans:\n      type: kitti\n"
                    f"      folder: {os.path.join(DATA, 'lidar_scans', 'kitti_00', 'velodyne')}\n"
                    "      times: times.txt\n")
        times = os.path.join(folder, "times.txt")
        out = os.path.join(self.tmp.name, "kitti_out")
        for stamps, named in (("0\n0.1\n0.1\n", ":3: field 't': repeats the stamp 0.1 of line 2"),
                              ("0\n0.2\n0.1\n", ":3: field 't': goes back before the stamp 0.2"),
                              ("0\nnan\n", ":2: field 't': 'nan' is not finite")):
            with self.subTest(stamps=stamps):
                with open(times, "w") as f:
                    f.write(stamps)
                code, _, err = run("odometry", "--dataset", folder, "--out", out,
                                   "--allow-outside-paths", check=False)
                self.assertEqual(code, 1)
                self.assertIn(times + named, err)
                self.assertFalse(os.path.exists(out))

    def test_unknown_robot_is_named(self):
        code, _, err = run("odometry", "--dataset", self.dataset, "--robot", "zz", "--out",
                           os.path.join(self.tmp.name, "x"), check=False)
        self.assertEqual(code, 1)
        self.assertIn("'zz'", err)


class Errors(unittest.TestCase):
    """Bad input: a non-zero exit and one line naming the file and the problem."""

    def test_every_subcommand_has_help(self):
        for args in (["--help"], ["eval", "ate", "--help"], ["eval", "rpe", "--help"],
                     ["convert", "--help"], ["config", "--help"], ["demo", "--help"],
                     ["version", "--help"]):
            with self.subTest(args=args):
                code, out, _ = run(*args, check=False)
                self.assertEqual(code, 0)
                self.assertIn("Usage", out)

    def test_version(self):
        _, out, _ = run("version")
        self.assertTrue(out.startswith("dcl-slam "))

    def test_missing_file_is_named(self):
        code, _, err = run("eval", "ate", "--gt", "/nonexistent/gt.txt", "--est",
                           os.path.join(EVO, "KITTI_00_ORB.txt"), "--format", "kitti",
                           check=False)
        self.assertEqual(code, 1)
        self.assertIn("/nonexistent/gt.txt", err)
        self.assertEqual(len(err.strip().splitlines()), 1)

    def test_corrupt_pose_file_names_the_line(self):
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 zero 0 0 1 0\n")
        try:
            code, _, err = run("eval", "ate", "--gt", f.name, "--est", f.name, "--format",
                               "kitti", check=False)
        finally:
            os.unlink(f.name)
        self.assertEqual(code, 1)
        self.assertIn(f"{f.name}:2", err)

    def test_bad_alignment_is_refused(self):
        gt = os.path.join(EVO, "KITTI_00_gt.txt")
        code, _, err = run("eval", "ate", "--gt", gt, "--est", gt, "--format", "kitti",
                           "--align", "affine", check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("affine", err)

    def test_bad_numbers_are_refused_when_the_options_are_read(self):
        gt = os.path.join(EVO, "KITTI_00_gt.txt")
        ate = ["eval", "ate", "--gt", gt, "--est", gt, "--format", "kitti"]
        rpe = ["eval", "rpe", "--gt", gt, "--est", gt, "--format", "kitti"]
        cases = [
            (ate + ["--reference-robot", "-1"], "--reference-robot: '-1' is negative"),
            (ate + ["--reference-robot", "nan"], "--reference-robot: 'nan' is not a finite number"),
            (ate + ["--max-diff", "nan"], "--max-diff: 'nan' is not a finite number"),
            (ate + ["--max-diff", "-0.01"], "--max-diff: '-0.01' is negative"),
            (rpe + ["--max-diff", "inf"], "--max-diff: 'inf' is not a finite number"),
            (ate + ["--offset", "nan"], "--offset: 'nan' is not a finite number"),
            (rpe + ["--offset", "-inf"], "--offset: '-inf' is not a finite number"),
            (["bench", "loops", "--max-error-m", "nan"], "--max-error-m: 'nan' is not a finite"),
            (["bench", "loops", "--max-error-m", "-1"], "--max-error-m: '-1' is negative"),
            (["bench", "loops", "--max-error-deg", "nan"], "--max-error-deg: 'nan' is not a"),
        ]
        for command in (["odometry"], ["bench", "odometry"], ["bench", "loops"], ["run"],
                        ["robot"], ["swarm"], ["bench", "system"]):
            cases += [(command + ["--max-frames", "-1"], "--max-frames: '-1' is negative"),
                      (command + ["--max-frames", "nan"], "--max-frames: 'nan' is not a finite")]
        for args, named in cases:
            with self.subTest(args=args):
                code, _, err = run(*args, check=False)
                self.assertNotEqual(code, 0)
                self.assertTrue(err.startswith("dcl-slam: error: "), err)
                self.assertEqual(len(err.strip().splitlines()), 1, err)
                self.assertIn(named, err)
        # A negative offset is a clock difference: allowed.
        code, _, _ = run(*ate, "--offset", "-0.5", "--max-diff", "0")
        self.assertEqual(code, 0)

    def test_file_system_errors_name_the_path(self):
        # A path the system cannot resolve (a symbolic link to itself, given
        # directly or as a robot's graph in a folder): the path first, then why.
        with tempfile.TemporaryDirectory() as tmp:
            os.symlink("loop", os.path.join(tmp, "loop"))
            graphs = os.path.join(tmp, "graphs")
            os.mkdir(graphs)
            os.symlink("0.g2o", os.path.join(graphs, "0.g2o"))
            for path in (os.path.join(tmp, "loop"), graphs):
                with self.subTest(path=path):
                    code, _, err = run("pgo", "--g2o", path, check=False)
                    self.assertEqual(code, 1)
                    self.assertTrue(err.startswith("dcl-slam: error: " + tmp), err)
                    self.assertIn("Too many levels of symbolic links", err)
                    self.assertNotIn("unexpected", err)
                    self.assertEqual(len(err.strip().splitlines()), 1, err)

    def test_unknown_scan_extension(self):
        scan = os.path.join(DATA, "lidar_scans", "kitti_00", "velodyne", "000000.bin")
        code, _, err = run("convert", scan, "/tmp/x.xyz", check=False)
        self.assertNotEqual(code, 0)
        self.assertIn(".xyz", err)

    def test_command_line_mistakes_get_the_same_one_line(self):
        for args, named, command in ((["run", "--dataset", "d", "--bogus"], "--bogus", "run "),
                                     (["eval", "ate", "--gt"], "--gt", "eval ate "),
                                     (["pgo"], "--g2o", "pgo "),
                                     (["nonsense"], "subcommand", "")):
            with self.subTest(args=args):
                code, out, err = run(*args, check=False)
                self.assertEqual(code, 2)
                lines = err.strip().splitlines()
                self.assertEqual(len(lines), 1, err)
                self.assertTrue(lines[0].startswith("dcl-slam: error: "), err)
                self.assertIn(named, lines[0])
                self.assertTrue(lines[0].endswith(f"(see dcl-slam {command}--help)"), err)

    def test_binary_bytes_in_a_message_are_escaped(self):
        with tempfile.NamedTemporaryFile("wb", suffix=".txt", delete=False) as f:
            f.write(b"1 2 \x1b[31m\x07\xff\xfe 4 5 6 7 8\n")
        try:
            code, _, err = run("eval", "ate", "--gt", f.name, "--est", f.name, check=False)
        finally:
            os.unlink(f.name)
        self.assertEqual(code, 1)
        self.assertNotIn("\x1b", err)
        self.assertNotIn("\x07", err)
        self.assertIn("\\x1b", err)
        self.assertEqual(len(err.strip().splitlines()), 1)


class Simulate(unittest.TestCase):
    """dcl-slam simulate: small dataset folders, exports other tools read, previews."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def path(self, *names):
        return os.path.join(self.dir, *names)

    def folder_files(self, folder):
        """{relative path: size} of every file under folder."""
        files = {}
        for root, _, names in os.walk(folder):
            for name in names:
                full = os.path.join(root, name)
                files[os.path.relpath(full, folder)] = os.path.getsize(full)
        return files

    def simulate_short(self, out, *extra):
        """One demo robot cut to 4 scans: seconds, not minutes."""
        return run("simulate", "--preset", "small-3", "--robots", "1", "--max-scans", "4",
                   "--out", out, *extra)

    def test_a_dataset_reads_nothing_outside_its_folder_unless_allowed(self):
        self.simulate_short(self.path("ds"))
        yaml_path = self.path("ds", "dataset.yaml")
        with open(yaml_path) as f:
            text = f.read()
        secret = self.path("secret.tum")
        shutil.copy(self.path("ds", "ground_truth", "a.tum"), secret)
        for name, edited in (
                ("climbing out", text.replace("ground_truth/a.tum", "../secret.tum")),
                ("absolute", text.replace("ground_truth/a.tum", secret)),
                ("robot name a path", text.replace("name: a\n", "name: ../../evil\n"))):
            with self.subTest(name):
                with open(yaml_path, "w") as f:
                    f.write(edited)
                out = self.path("out-" + name.replace(" ", "-"))
                code, _, err = run("run", "--dataset", self.path("ds"), "--out", out, check=False)
                self.assertEqual(code, 1)
                self.assertIn(yaml_path, err)
                self.assertIn("robots[0]", err)
                self.assertFalse(os.path.exists(out))
                self.assertFalse(os.path.exists(self.path("evil")))
        # The user may allow it explicitly, for data kept elsewhere.
        with open(yaml_path, "w") as f:
            f.write(text.replace("ground_truth/a.tum", secret))
        run("--allow-outside-paths", "run", "--dataset", self.path("ds"), "--out",
            self.path("allowed"))
        self.assertTrue(os.path.exists(self.path("allowed", "a", "trajectory.tum")))

    def test_demo_dataset_is_kilobytes_without_scans(self):
        _, out, _ = run("simulate", "--preset", "demo", "--out", self.path("demo"))
        files = self.folder_files(self.path("demo"))
        self.assertIn("dataset.yaml", files)
        self.assertEqual(sorted(f for f in files if f.endswith(".tum")),
                         ["ground_truth/a.tum", "ground_truth/b.tum", "ground_truth/c.tum"])
        self.assertFalse([f for f in files if f.endswith(".bin") or f.endswith(".bag")])
        self.assertLess(sum(files.values()), 1_000_000)
        self.assertIn("robot", out)
        self.assertIn("scans", out)
        with open(self.path("demo", "dataset.yaml")) as f:
            text = f.read()
        self.assertIn("type: sim", text)
        self.assertIn("ground_truth: T_world_sensor", text)

    def test_kitti_export_is_read_by_convert(self):
        _, out, _ = self.simulate_short(self.path("ds"), "--export", "kitti")
        velodyne = self.path("ds", "kitti", "a", "velodyne")
        self.assertEqual(sorted(os.listdir(velodyne)), [f"{i:06}.bin" for i in range(4)])
        with open(self.path("ds", "kitti", "a", "times.txt")) as f:
            self.assertEqual(len(f.read().split()), 4)
        self.assertTrue(os.path.exists(self.path("ds", "kitti", "a", "poses.txt")))
        self.assertTrue(os.path.exists(self.path("ds", "kitti", "dataset.yaml")))
        scan = os.path.join(velodyne, "000003.bin")
        _, converted, _ = run("convert", scan, self.path("scan.pcd"))
        points = os.path.getsize(scan) // 16
        self.assertGreater(points, 5000)
        self.assertIn(f"{points} points", converted)

    def test_same_seed_gives_bit_identical_scans(self):
        self.simulate_short(self.path("one"), "--seed", "5", "--export", "kitti")
        self.simulate_short(self.path("two"), "--seed", "5", "--export", "kitti")
        self.simulate_short(self.path("three"), "--seed", "6", "--export", "kitti")
        scan = os.path.join("kitti", "a", "velodyne", "000002.bin")
        with open(self.path("one", scan), "rb") as a, open(self.path("two", scan), "rb") as b, \
                open(self.path("three", scan), "rb") as c:
            one, two, three = a.read(), b.read(), c.read()
        self.assertEqual(one, two)
        self.assertNotEqual(one, three)

    def test_bag_export_is_listed_by_convert(self):
        self.simulate_short(self.path("ds"), "--export", "bag")
        bag = self.path("ds", "bag", "a", "scans.bag")
        run("convert", bag, self.path("scans"), "--topic", "/points")
        self.assertEqual(len([n for n in os.listdir(self.path("scans")) if n.endswith(".bin")]), 4)
        run("convert", bag, self.path("gt.tum"), "--topic", "/ground_truth")
        with open(self.path("gt.tum")) as f:
            self.assertEqual(len([l for l in f if l.strip() and not l.startswith("#")]), 4)

    def test_mcap_export_is_read_by_convert_and_as_a_dataset(self):
        self.simulate_short(self.path("ds"), "--export", "mcap")
        bag = self.path("ds", "mcap", "a", "scans.mcap")
        with open(self.path("ds", "mcap", "dataset.yaml")) as f:
            text = f.read()
        self.assertIn("type: mcap", text)
        self.assertIn("file: a/scans.mcap", text)
        run("convert", bag, self.path("scans"), "--topic", "/points")
        self.assertEqual(len([n for n in os.listdir(self.path("scans")) if n.endswith(".bin")]), 4)
        run("convert", bag, self.path("gt.tum"), "--topic", "/ground_truth")
        with open(self.path("gt.tum")) as f:
            self.assertEqual(len([l for l in f if l.strip() and not l.startswith("#")]), 4)
        code, _, err = run("convert", bag, self.path("x.tum"), check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("/ground_truth (nav_msgs/msg/Odometry, 4 messages)", err)
        self.assertIn("/points (sensor_msgs/msg/PointCloud2, 4 messages)", err)
        # The exported dataset runs as the simulated one: its scans from the MCAP files.
        run("odometry", "--dataset", self.path("ds", "mcap"), "--robot", "a", "--out",
            self.path("odom"))
        with open(self.path("odom", "metrics.json")) as f:
            self.assertEqual(json.load(f)["frames"]["frames"], 4)

    def test_preview_writes_two_pngs(self):
        self.simulate_short(self.path("ds"))
        run("simulate", "--preview", self.path("ds"))
        for name in ("preview_world.png", "preview_scan.png"):
            with open(self.path("ds", name), "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n", name)

    def test_unknown_preset_lists_the_presets(self):
        code, _, err = run("simulate", "--preset", "mars", "--out", self.path("x"), check=False)
        self.assertEqual(code, 1)
        self.assertIn("mars", err)
        for name in ("kitti00-3", "kitti05-3", "kitti08-2", "campus-3", "campus-9", "aliasing-3",
                     "small-3", "demo", "crossing-2"):
            self.assertIn(name, err)
        self.assertEqual(len(err.strip().splitlines()), 1)
        self.assertFalse(os.path.exists(self.path("x")))

    def test_help_lists_presets(self):
        for args in (["simulate", "--help"], ["bench", "sim", "--help"]):
            with self.subTest(args=args):
                code, out, _ = run(*args, check=False)
                self.assertEqual(code, 0)
                self.assertIn("Usage", out)
        self.assertIn("kitti05-3", run("simulate", "--help")[1])

    def test_bench_sim_reports_rate(self):
        self.simulate_short(self.path("ds"))
        _, out, _ = run("bench", "sim", "--dataset", self.path("ds"), "--threads", "2", "--json")
        result = json.loads(out)
        self.assertEqual(result["scans"], 4)
        self.assertGreater(result["scans_per_s"], 0)
        self.assertAlmostEqual(result["realtime_factor"], result["scans_per_s"] / 10.0)


    def test_bench_sensor_holds_simulated_sweeps_to_real_ones(self):
        run("simulate", "--preset", "small-3", "--robots", "1", "--max-scans", "60",
            "--sensor", "hdl64", "--out", self.path("ds"))
        _, out, _ = run("bench", "sensor", "--dataset", self.path("ds"), "--scans", "2",
                        "--data", DATA, "--json")
        result = json.loads(out)
        self.assertEqual(result["real_scans"], 10)
        self.assertEqual(result["simulated_scans"], 2)
        rows = {row["statistic"]: row for row in result["statistics"]}
        noise = rows["plane noise 2-10 m (m)"]
        self.assertLess(noise["real"][0], noise["real"][1])
        self.assertGreater(noise["simulated_median"], 0.005)
        names = [line["trajectory"] for line in result["vehicle"]]
        self.assertEqual(names, ["real KITTI 00", "real KITTI 05", "real KITTI 08", "simulated a"])
        self.assertGreater(result["vehicle"][0]["pitch_sigma_deg"], 0.1)
        # A folder without scans is named.
        os.makedirs(self.path("empty"))
        code, _, err = run("bench", "sensor", "--dataset", self.path("ds"), "--real",
                           self.path("empty"), check=False)
        self.assertNotEqual(code, 0)
        self.assertIn(self.path("empty"), err)
        self.assertIn("holds no scan", err)

    def test_bench_system_runs_each_preset_in_every_seed(self):
        work, table = self.path("work"), self.path("system.md")
        _, out, _ = run("bench", "system", "--datasets", "demo", "--scale", "none", "--seeds",
                        "1,2", "--max-frames", "40", "--threads", "2", "--work", work,
                        "--markdown", table, "--json")
        runs = json.loads(out)["datasets"]
        self.assertEqual([(r["summary"]["dataset"], r["summary"]["seed"]) for r in runs],
                         [("demo", 1), ("demo-s2", 2)])
        for name, seed in (("demo", 1), ("demo-s2", 2)):
            with open(os.path.join(work, name, "dataset.yaml")) as f:
                self.assertRegex(f.read(), rf"\n  seed: {seed}\b")
            self.assertTrue(os.path.isfile(os.path.join(work, name + "-run", "metrics.json")))
        # Two worlds: the same robot's odometry errs otherwise in each.
        self.assertNotEqual(runs[0]["metrics"]["robots"][0]["ate_rmse_odometry_only"],
                            runs[1]["metrics"]["robots"][0]["ate_rmse_odometry_only"])
        with open(table) as f:
            text = f.read()
        self.assertIn("Across seeds", text)
        self.assertRegex(text, r"\| `demo` \| 2 \| -?\d+ % / -?\d+ % \| -?\d+ % \| \d of 6 \|")
        code, _, err = run("bench", "system", "--datasets", "demo", "--seeds", "0", "--work",
                           work, check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("--seeds", err)

    def test_bench_system_puts_traffic_in_worlds_of_their_own(self):
        work = self.path("work")
        _, out, _ = run("bench", "system", "--datasets", "demo", "--scale", "none",
                        "--max-frames", "20", "--threads", "2", "--traffic", "1", "--work",
                        work, "--json")
        self.assertEqual([r["summary"]["dataset"] for r in json.loads(out)["datasets"]],
                         ["demo-t1"])
        with open(os.path.join(work, "demo-t1", "dataset.yaml")) as f:
            self.assertRegex(f.read(), r"\n  traffic: 1\b")
        code, _, err = run("bench", "system", "--datasets", "demo", "--traffic", "11", "--work",
                           work, check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("--traffic", err)


class Place(DemoDataset):
    """dcl-slam bench place: inter-robot place recognition on the demo swarm."""

    def bench(self, descriptor):
        out = os.path.join(self.tmp.name, descriptor)
        _, stdout, _ = run("bench", "place", "--dataset", self.dataset, "--descriptor", descriptor,
                           "--every", "2", "--out", out, "--json")
        return out, json.loads(stdout)

    def test_iris_finds_inter_robot_loops_and_writes_the_curve(self):
        out, m = self.bench("iris")
        curve = m["curve"]
        self.assertGreater(m["keyframes"], 100)
        self.assertGreater(curve["positives"], 0)
        self.assertGreaterEqual(curve["recall_at_100_precision"], 0.0)
        self.assertLessEqual(curve["recall_at_100_precision"], 1.0)
        self.assertGreater(m["true_loops"], 0)
        with open(os.path.join(out, "pr.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), len({r["threshold"] for r in rows}))
        for row in rows:
            self.assertTrue(0.0 <= float(row["precision"]) <= 1.0)
            self.assertTrue(0.0 <= float(row["recall"]) <= 1.0)
        with open(os.path.join(out, "pr.svg")) as f:
            svg = f.read()
        self.assertIn("<polyline", svg)
        self.assertTrue(svg.rstrip().endswith("</svg>"))
        self.assertGreater(m["timing_ms"]["describe_mean"], 0.0)

    def test_scan_context_runs_too(self):
        _, m = self.bench("scancontext")
        self.assertEqual(m["descriptor"], "scancontext")
        self.assertLessEqual(m["curve"]["recall_at_100_precision"], 1.0)

    def test_unknown_descriptor_is_named(self):
        code, _, err = run("bench", "place", "--dataset", self.dataset, "--descriptor", "m2dp",
                           "--out", os.path.join(self.tmp.name, "x"), check=False)
        self.assertEqual(code, 1)
        self.assertIn("'m2dp'", err)


OUTLIERS = os.path.join(DATA, "pose_graphs", "multi_robot_outliers")


def read_g2o_edges(path):
    """(from id, to id) of every EDGE line of a g2o file."""
    with open(path) as f:
        return [(int(t[1]), int(t[2])) for t in (line.split() for line in f)
                if t and t[0].startswith("EDGE")]


def symbol_name(symbol):
    return chr(symbol >> 56) + str(symbol & ((1 << 56) - 1))


IDENTITY_INFORMATION = " ".join("1" if r == c else "0" for r in range(6) for c in range(r, 6))


def g2o_vertex(i):
    return f"VERTEX_SE3:QUAT {i} {i} 0 0 0 0 0 1\n"


def g2o_edge(a, b, information=IDENTITY_INFORMATION):
    return f"EDGE_SE3:QUAT {a} {b} 1 0 0 0 0 0 1 {information}\n"


# Graphs pgo and pcm refuse: {file: content}, and what the one error line names.
CHAIN = g2o_vertex(0) + g2o_vertex(1) + g2o_edge(0, 1)
A, B = ord("a") << 56, ord("b") << 56
BAD_GRAPHS = (
    ({"dangling.g2o": CHAIN + g2o_edge(1, 7)},
     "dangling.g2o:4: field 'to': edge to vertex 7, which the file does not define"),
    ({"zero.g2o": g2o_vertex(0) + g2o_vertex(1) + g2o_edge(0, 1, " ".join(["0"] * 21))},
     "zero.g2o:3: field 'information': information matrix is zero"),
    ({"negative.g2o": g2o_vertex(0) + g2o_vertex(1) + g2o_edge(0, 1, "-" + IDENTITY_INFORMATION)},
     "negative.g2o:3: field 'information': information matrix is not positive semi-definite"),
    ({"gap/0.g2o": g2o_vertex(A) + g2o_vertex(A + 1) + g2o_edge(A, A + 1),
      "gap/2.g2o": g2o_vertex(B) + g2o_vertex(B + 1) + g2o_edge(B, B + 1)},
     "gap: 1.g2o is missing"),
    ({"twice/0.g2o": g2o_vertex(A) + g2o_vertex(A + 1) + g2o_edge(A, A + 1),
      "twice/1.g2o": g2o_vertex(B) + g2o_vertex(A + 1) + g2o_edge(B, A + 1)},
     "twice/1.g2o:2: field 'id': vertex a1 is defined in 0.g2o line 2 already"),
    ({"loop_to_nowhere/0.g2o": g2o_vertex(A) + g2o_vertex(A + 1) + g2o_edge(A, A + 1)
      + g2o_edge(A + 1, B + 5),
      "loop_to_nowhere/1.g2o": g2o_vertex(B) + g2o_vertex(B + 1) + g2o_edge(B, B + 1)},
     "loop_to_nowhere/0.g2o:4: field 'to': edge to vertex b5, which no robot graph of the "
     "folder defines"),
)


def check_bad_graphs(test, *command):
    """Each of BAD_GRAPHS makes `dcl-slam *command GRAPH` fail with one line naming it."""
    for files, named in BAD_GRAPHS:
        with tempfile.TemporaryDirectory() as tmp, test.subTest(graph=named):
            for name, content in files.items():
                os.makedirs(os.path.dirname(os.path.join(tmp, name)), exist_ok=True)
                with open(os.path.join(tmp, name), "w") as f:
                    f.write(content)
            graph = os.path.join(tmp, next(iter(files)).split("/")[0])
            code, out, err = run(*command, graph, check=False)
            test.assertEqual(code, 1, out)
            test.assertEqual(len(err.strip().splitlines()), 1, err)
            test.assertTrue(err.startswith("dcl-slam: error: "), err)
            test.assertIn(os.path.join(tmp, named), err)


def check_unknown_lines_skipped(test, *command):
    """A damaged line of a single file fails the command, and --skip-unknown-lines skips it."""
    with tempfile.TemporaryDirectory() as tmp:
        graph = os.path.join(tmp, "damaged.g2o")
        with open(graph, "w") as f:
            f.write(g2o_vertex(0) + "0410268 0.7588833\n" + g2o_vertex(1) + g2o_edge(0, 1))
        code, _, err = run(*command, graph, check=False)
        test.assertEqual(code, 1)
        test.assertIn(f"{graph}:2: field 'tag'", err)
        code, out, err = run(*command, graph, "--skip-unknown-lines", "--json")
        test.assertEqual(json.loads(out)["graph"], graph)
        test.assertIn(f"{graph}:2: skipped a line with an unknown tag", err)


class Pcm(unittest.TestCase):
    """dcl-slam pcm: outlier rejection on the benchmark graphs with outlier loops."""

    def pcm(self, graph, *extra):
        _, out, _ = run("pcm", "--graph", os.path.join(OUTLIERS, graph), *extra, "--json")
        return json.loads(out)

    def test_csail_against_its_reference_read_independently(self):
        folder = os.path.join("mixrobust_real2d_split", "CSAIL", "spilt_190random")
        reference = os.path.join(OUTLIERS, folder, "fullgraph_without_outliers.g2o")
        m = self.pcm(folder, "--reference", reference)
        self.assertEqual(m["loops"], 299)
        self.assertEqual(m["kept"] + m["rejected"], m["loops"])
        self.assertGreaterEqual(m["precision"], 0.99)
        self.assertGreaterEqual(m["recall"], 0.99)
        self.assertGreater(m["seconds"], 0.0)
        [pair] = m["pairs"]
        self.assertEqual(pair["robots"], ["a", "b"])
        self.assertEqual(len(pair["kept_loops"]), m["kept"])
        # The full graph numbers robot a's vertices first: score the kept list here.
        with open(os.path.join(OUTLIERS, folder, "0.g2o")) as f:
            robot_a = sum(1 for line in f if line.startswith("VERTEX"))
        name = lambda i: f"a{i}" if i < robot_a else f"b{i - robot_a}"
        inliers = set()
        for a, b in read_g2o_edges(reference):
            if (a < robot_a) != (b < robot_a):
                inliers.add("-".join(sorted((name(a), name(b)))))
        candidates = set()
        for robot in ("0.g2o", "1.g2o"):
            for a, b in read_g2o_edges(os.path.join(OUTLIERS, folder, robot)):
                if a >> 56 != b >> 56:
                    candidates.add("-".join(sorted((symbol_name(a), symbol_name(b)))))
        kept = set(pair["kept_loops"])
        self.assertEqual(kept | set(pair["rejected_loops"]), candidates)
        self.assertAlmostEqual(m["precision"], len(kept & inliers) / len(kept))
        self.assertAlmostEqual(m["recall"], len(kept & inliers) / len(candidates & inliers))

    def test_without_reference_scores_are_null(self):
        m = self.pcm(os.path.join("robust_distributed_mapper", "pairwise_consistency_maximization",
                                  "spoiled", "simulation", "example_8robots"))
        self.assertIsNone(m["precision"])
        self.assertIsNone(m["recall"])
        self.assertEqual(m["robots"], 8)
        self.assertEqual(len(m["pairs"]), 28)
        self.assertEqual(sum(p["loops"] for p in m["pairs"]), m["loops"])
        self.assertEqual(sum(p["kept"] for p in m["pairs"]), m["kept"])

    def test_threshold_from_option_and_configuration(self):
        graph = os.path.join("mixrobust_real2d_split", "INTEL", "spilt_5_6_random")
        default = self.pcm(graph)
        self.assertEqual(default["threshold"], 5.348)
        strict = self.pcm(graph, "--threshold", "0.5")
        self.assertLessEqual(strict["kept"], default["kept"])  # fewer consistent pairs
        with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
            f.write("pcm:\n  threshold: 0.5\n")
        try:
            configured = self.pcm(graph, "--config", f.name)
        finally:
            os.unlink(f.name)
        self.assertEqual(configured["threshold"], 0.5)
        self.assertEqual(configured["pairs"][0]["kept_loops"], strict["pairs"][0]["kept_loops"])

    def test_human_readable_summary(self):
        folder = os.path.join(OUTLIERS, "mixrobust_real2d_split", "INTEL", "spilt_5_6_spoiled")
        _, out, _ = run("pcm", "--graph", folder, "--reference",
                        os.path.join(folder, "fullgraph_without_outliers.g2o"))
        self.assertIn("a-b: 123 loops", out)
        self.assertIn("precision", out)
        code, out, _ = run("pcm", "--help", check=False)
        self.assertEqual(code, 0)
        self.assertIn("--reference", out)

    def test_damaged_line_is_named_and_can_be_skipped(self):
        graph = os.path.join(OUTLIERS, "robust_distributed_mapper",
                             "pairwise_consistency_maximization", "spoiled", "simulation",
                             "example_2robots")
        code, _, err = run("pcm", "--graph", graph, check=False)
        self.assertEqual(code, 1)
        self.assertIn("1.g2o:16", err)
        self.assertEqual(len(err.strip().splitlines()), 1)
        _, out, err = run("pcm", "--graph", graph, "--skip-unknown-lines", "--json")
        self.assertEqual(json.loads(out)["loops"], 20)
        self.assertIn("1.g2o:16", err)

    def test_bad_graphs_are_named_by_file_and_line(self):
        check_bad_graphs(self, "pcm", "--graph")

    def test_unknown_lines_of_a_single_file_can_be_skipped(self):
        check_unknown_lines_skipped(self, "pcm", "--graph")

    def test_reference_of_another_graph_is_refused(self):
        code, _, err = run(
            "pcm", "--graph", os.path.join(OUTLIERS, "mixrobust_real2d_split", "CSAIL", "spilt"),
            "--reference", os.path.join(OUTLIERS, "mixrobust_real2d_split", "INTEL", "spilt",
                                        "fullgraph_without_outliers.g2o"), check=False)
        self.assertEqual(code, 1)
        self.assertIn("not a reference of this graph", err)
        self.assertIn("INTEL", err)



class AliasingCorridor(unittest.TestCase):
    """The perceptual-aliasing corridor, where identical blocks repeat every
    48 m and only the cars parked along it for a while (traffic) tell a place
    from its repeats, simulated into a folder of its own per test class. World
    4: in world 1 nothing tells a place from its repeats (every match is
    refused), in the others 54-98 loops are kept, none wrong (BENCHMARKS.md,
    "No false loop in five worlds"); 4 keeps the fewest."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "aliasing-3")
        run("simulate", "--preset", "aliasing-3", "--seed", "4", "--traffic", "1", "--out",
            cls.dataset)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()


class Loops(AliasingCorridor):
    """dcl-slam bench loops: place search, verification and PCM end to end on
    the aliasing corridor."""

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.out = os.path.join(cls.tmp.name, "loops")
        _, stdout, _ = run("bench", "loops", "--dataset", cls.dataset, "--out", cls.out, "--json")
        cls.metrics = json.loads(stdout)

    def test_no_false_loop_survives_while_true_ones_do(self):
        loops = self.metrics["loops"]
        # Most matches land on a place that repeats on its own robot's route
        # about as closely (335 of 395 in this world): they are refused,
        # whether the match was the true place (95) or a repeat of it...
        self.assertGreater(loops["refused_ambiguous"], 150)
        self.assertGreater(loops["refused_ambiguous"], 2 * loops["refused_ambiguous_true_place"])
        # ...and of the places the parked cars make distinct, PCM keeps every
        # one verified right (54) and none wrong.
        self.assertEqual(loops["kept_wrong"], 0)
        self.assertEqual(loops["precision"], 1.0)
        self.assertGreater(loops["kept_correct"], 20)
        self.assertGreater(loops["recall"], 0.9)
        self.assertEqual(loops["withdrawn_correct"], 0)

    def test_every_candidate_is_graded_in_the_csv(self):
        with open(os.path.join(self.out, "loops.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), self.metrics["loops"]["candidates"])
        kept = [r for r in rows if r["kept"] == "1"]
        self.assertEqual(len(kept), self.metrics["loops"]["kept"])
        for r in kept:
            self.assertEqual(r["verified"], "1")
            self.assertLess(float(r["error_m"]), 1.0)  # the pose it measures is right
        # The compact verification cloud of a VLP-16 keyframe is a few kB.
        self.assertLess(self.metrics["loops"]["wire_bytes_mean"], 25000)


class LoopsLive(AliasingCorridor):
    """dcl-slam run on the aliasing corridor, its robots live over the
    simulated radio (a test of its own, so that ctest runs it beside Loops'
    offline bench)."""

    def test_robots_running_live_keep_no_false_loop(self):
        # Live, a robot matches a neighbour's place before either has passed
        # the block's repeat: the robot that asked judges the loop again when
        # either robot passes a place like it, and withdraws it then (8 in
        # this world, where a and c keep 12). With the corridor bare of
        # parked cars, robots a and c of world 1 held three loops 336 m
        # off, their only link, while a place was tested against the
        # neighbour's repeats but not against the own.
        config = os.path.join(self.tmp.name, "unlimited.yaml")
        with open(config, "w") as f:
            f.write("radio: {range: 0}\n")
        _, stdout, _ = run("--config", config, "run", "--dataset", self.dataset, "--out",
                           os.path.join(self.tmp.name, "run"), "--json")
        robots = json.loads(stdout)["robots"]
        for r in robots:
            self.assertEqual(r["inter_loops_accepted_wrong"], 0, r["name"])
        withdrawn = sum(r["counters"].get("inter_loops_withdrawn_repeated", 0) for r in robots)
        refused = sum(r["counters"].get("candidates_ambiguous", 0) for r in robots)
        self.assertGreater(withdrawn, 0)
        self.assertGreater(refused, 50)
        self.assertGreater(sum(r["inter_loops_accepted"] for r in robots), 0)



class Crossing(unittest.TestCase):
    """dcl-slam run on crossing-2: two robots whose streets cross once, each
    seeing the other's place for a few keyframes, and nothing else shared.
    Their loops there are all they have: the robots must end in one frame, and
    no loop kept may be wrong."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "crossing-2")
        run("simulate", "--preset", "crossing-2", "--out", cls.dataset)
        _, stdout, _ = run("run", "--dataset", cls.dataset, "--out",
                           os.path.join(cls.tmp.name, "run"), "--json")
        cls.metrics = json.loads(stdout)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_robots_that_met_once_share_one_frame(self):
        robots = self.metrics["robots"]
        self.assertEqual(len(robots), 2)
        self.assertEqual(len({r["frame"] for r in robots}), 1, robots)
        for r in robots:
            self.assertGreater(r["inter_loops_accepted"], 0, r["name"])
            self.assertEqual(r["inter_loops_accepted_wrong"], 0, r["name"])

    def test_the_joint_map_is_as_good_as_each_robots_own(self):
        # Under one alignment of both robots, each within 2x its own alignment's
        # error, pooled over both (a robot that drifts more drags the other's
        # joint error: one rigid fit cannot undo the first robot's drift).
        robots = self.metrics["robots"]
        own = math.sqrt(sum(r["ate_rmse"] ** 2 for r in robots) / len(robots))
        joint = math.sqrt(sum(r["ate_rmse_joint"] ** 2 for r in robots) / len(robots))
        self.assertLess(joint, 2.0 * own, robots)
        for r in robots:
            self.assertLess(r["ate_rmse_joint"], 1.0, r["name"])


class Pgo(unittest.TestCase):
    """dcl-slam pgo: distributed pose-graph optimisation beside the centralized optimum."""

    GRIDS = os.path.join(DATA, "pose_graphs", "3d")
    MAPPER = os.path.join(DATA, "pose_graphs", "multi_robot", "distributed_mapper")

    def pgo(self, *args):
        _, stdout, _ = run("pgo", *args, "--json")
        return json.loads(stdout)

    def test_dgs_and_refinement_reach_the_centralized_optimum(self):
        graph = os.path.join(self.GRIDS, "smallGrid3D.g2o")
        dgs = self.pgo("--g2o", graph, "--robots", "4", "--method", "dgs")
        refined = self.pgo("--g2o", graph, "--robots", "4", "--method", "dgs+refine")
        for m in (dgs, refined):
            for field in ("cost", "centralized_cost", "cost_ratio", "iterations_rotation",
                          "iterations_pose", "bytes_total", "seconds"):
                self.assertIn(field, m)
            self.assertEqual(m["robots"], 4)
            self.assertAlmostEqual(m["cost_ratio"], m["cost"] / m["centralized_cost"], places=9)
            self.assertGreater(m["iterations_rotation"], 0)
            self.assertGreater(m["bytes_total"], 0)
            self.assertLess(m["bytes_total"], m["bytes_paper_format"])
        self.assertGreaterEqual(dgs["cost_ratio"], 1.0 - 1e-9)
        self.assertLessEqual(refined["cost_ratio"], 1.001)
        self.assertLessEqual(refined["cost"], dgs["cost"])

    def test_per_robot_folders_are_read_as_they_are_and_the_result_written(self):
        out = os.path.join(tempfile.mkdtemp(), "result.g2o")
        m = self.pgo("--g2o", os.path.join(self.MAPPER, "example_4robots"), "--method", "dgs",
                     "--out", out)
        self.assertEqual(m["robots"], 4)
        with open(out) as f:
            vertices = sum(1 for line in f if line.startswith("VERTEX_SE3"))
        self.assertEqual(vertices, m["nodes"])
        central = self.pgo("--g2o", out, "--method", "centralized")
        self.assertAlmostEqual(central["cost_ratio"], 1.0, places=9)

    def test_bad_requests_are_named(self):
        graph = os.path.join(self.GRIDS, "smallGrid3D.g2o")
        code, _, err = run("pgo", "--g2o", graph, "--method", "admm", check=False)
        self.assertEqual(code, 1)
        self.assertIn("'admm'", err)
        code, _, err = run("pgo", "--g2o", os.path.join(self.MAPPER, "example_4robots"),
                           "--robots", "2", check=False)
        self.assertEqual(code, 1)
        self.assertIn("4 robots already", err)

    def test_bad_graphs_are_named_by_file_and_line_and_nothing_is_written(self):
        out = os.path.join(tempfile.mkdtemp(), "result.g2o")
        check_bad_graphs(self, "pgo", "--method", "centralized", "--out", out, "--g2o")
        self.assertFalse(os.path.exists(out))

    def test_unknown_lines_of_a_file_or_a_folder_can_be_skipped(self):
        check_unknown_lines_skipped(self, "pgo", "--method", "centralized", "--g2o")
        folder = os.path.join(OUTLIERS, "robust_distributed_mapper",
                              "pairwise_consistency_maximization", "spoiled", "simulation",
                              "example_2robots")
        code, _, err = run("pgo", "--g2o", folder, check=False)
        self.assertEqual(code, 1)
        self.assertIn("1.g2o:16", err)
        m = self.pgo("--g2o", folder, "--method", "centralized", "--skip-unknown-lines")
        self.assertEqual(m["robots"], 2)


if __name__ == "__main__":
    unittest.main()




class Ping(unittest.TestCase):
    """dcl-slam ping: robot processes over Cyclone DDS on loopback hear each other and get
    every test broadcast exactly once, also when met late and across a restart.

    Each test has its own DDS domain (50..60, below 102: the fixed ports of higher
    domains are among the ephemeral ports any socket may hold) and a swarm name with
    this process id, so parallel test runs stay apart. Timing margins are seconds, never fractions of one."""

    MESSAGES = 5
    PERIOD = 0.2
    EPOCH_2024 = 1704067200  # 2024-01-01 00:00 UTC, the default incarnation's origin

    def start(self, robot, domain, duration, *extra):
        args = [DCL_SLAM, "ping", "--robot", str(robot), "--messages", str(self.MESSAGES),
                "--period", str(self.PERIOD), "--duration", str(duration), "--domain",
                str(domain), "--swarm", f"cli-test-{os.getpid()}", "--interface", "lo",
                "--json", *extra]
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.addCleanup(self.stop, proc)
        return proc

    @staticmethod
    def stop(proc):
        if proc.poll() is None:
            proc.kill()
            proc.communicate()

    def finish(self, proc):
        out, err = proc.communicate(timeout=120)
        self.assertEqual(proc.returncode, 0, err)
        return json.loads(out)

    def assertAllOnce(self, report, peer, incarnation=None):
        """Every number 0..K-1 of the peer's life (its latest one by default), once."""
        lives = report["lives"][str(peer)]
        life = lives[-1] if incarnation is None else \
            next(l for l in lives if l["incarnation"] == incarnation)
        where = f"robot {report['robot']} from robot {peer}"
        self.assertEqual(life["received"], list(range(self.MESSAGES)), where)
        self.assertEqual(life["count"], self.MESSAGES, where)
        self.assertEqual(life["duplicates"], 0, where)
        self.assertIsNotNone(life["complete_at"], where)

    def test_three_robots_exchange(self):
        before = time.time()
        procs = [self.start(robot, 50, 5) for robot in range(3)]
        reports = [self.finish(p) for p in procs]
        after = time.time()
        for robot, r in enumerate(reports):
            others = [o for o in range(3) if o != robot]
            self.assertEqual(r["robot"], robot)
            self.assertEqual(r["neighbours"], others)
            self.assertEqual(r["present"], others)
            self.assertEqual(sorted(r["received"]), [str(o) for o in others])
            for peer in others:
                self.assertEqual(len(r["lives"][str(peer)]), 1)
                self.assertAllOnce(r, peer)
            self.assertEqual(r["duplicates"], 0)
            self.assertEqual(r["sent"]["descriptor"], self.MESSAGES)
            self.assertEqual(r["delivered"]["descriptor"], 2 * self.MESSAGES)
            self.assertEqual(r["dropped"]["stale_incarnation"], 0)
            self.assertCountEqual([(e["type"], e["robot"]) for e in r["events"]],
                                  [("appeared", peer) for peer in others])
            self.assertFalse(r["interrupted"])
            # The default incarnation: tenths of a second since 2024-01-01 UTC.
            self.assertGreaterEqual(r["incarnation"], int((before - self.EPOCH_2024) * 10))
            self.assertLessEqual(r["incarnation"], int((after - self.EPOCH_2024) * 10) + 1)

    def test_late_joiner_gets_everything(self):
        early = [self.start(robot, 51, 10) for robot in (0, 1)]
        time.sleep(3.5)  # robots 0 and 1 send for 0.8 s after they start
        late = self.start(2, 51, 5)
        r2 = self.finish(late)
        r0, r1 = (self.finish(p) for p in early)
        for r in (r0, r1):
            last_sent = r["started_at"] + (self.MESSAGES - 1) * self.PERIOD
            self.assertGreater(r2["started_at"], last_sent + 1.0, "robot 2 did not join late")
            self.assertAllOnce(r2, r["robot"])
            self.assertAllOnce(r, 2)
            self.assertAllOnce(r, 1 - r["robot"])
            # Robot 2 missed every original broadcast: it got them as retransmissions.
            self.assertGreaterEqual(r["resent"]["descriptor"], self.MESSAGES)
            self.assertIn(("appeared", 2), [(e["type"], e["robot"]) for e in r["events"]])
        self.assertEqual(r2["neighbours"], [0, 1])
        self.assertEqual(r2["duplicates"] + r0["duplicates"] + r1["duplicates"], 0)

    def test_killed_robot_restarts_and_catches_up(self):
        steady = [self.start(robot, 52, 11) for robot in (0, 2)]
        first = self.start(1, 52, 60, "--incarnation", "1000")
        time.sleep(3)
        first.send_signal(signal.SIGKILL)
        first.communicate(timeout=30)
        second = self.start(1, 52, 5, "--incarnation", "1001")
        r1 = self.finish(second)
        r0, r2 = (self.finish(p) for p in steady)
        # The new life has no memory: it gets everything again, once.
        self.assertEqual(r1["incarnation"], 1001)
        self.assertEqual(r1["neighbours"], [0, 2])
        for peer in (0, 2):
            self.assertEqual(len(r1["lives"][str(peer)]), 1)
            self.assertAllOnce(r1, peer)
        self.assertEqual(r1["duplicates"], 0)
        for r in (r0, r2):
            self.assertEqual([l["incarnation"] for l in r["lives"]["1"]], [1000, 1001])
            self.assertAllOnce(r, 1, 1000)
            self.assertAllOnce(r, 1, 1001)
            self.assertEqual(r["received"]["1"], list(range(self.MESSAGES)))
            self.assertIn(("restarted", 1), [(e["type"], e["robot"]) for e in r["events"]])
            self.assertAllOnce(r, 2 - r["robot"])
            self.assertEqual(r["duplicates"], 0)

    def test_signal_ends_early_with_summary_and_options_override_config(self):
        with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
            f.write("dds:\n  domain: 7\n  swarm: from-config\n"
                    "messenger:\n  heartbeat_period: 0.1\n")
        self.addCleanup(os.unlink, f.name)
        proc = subprocess.Popen([DCL_SLAM, "--config", f.name, "ping", "--robot", "3",
                                 "--domain", "53", "--interface", "lo", "--duration", "120"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.addCleanup(self.stop, proc)
        time.sleep(2)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
        self.assertEqual(proc.returncode, 0, err)
        self.assertIn("robot 3", out)
        self.assertIn("swarm 'from-config', DDS domain 53 on lo", out)
        self.assertIn("interrupted", out)
        self.assertIn("neighbours heard: none", out)
        # heartbeat_period 0.1 s from the config: far more beats than the default 1 s gives.
        beats = int(re.search(r"sent: .*heartbeat (\d+)", out).group(1))
        self.assertGreaterEqual(beats, 8)

    def test_bad_options_are_named(self):
        for args, named in ((["--robot", "255"], "--robot"),
                            (["--robot", "0", "--domain", "300"], "domain"),
                            (["--robot", "0", "--swarm", "*"], "swarm"),
                            (["--robot", "0", "--duration", "0"], "--duration")):
            with self.subTest(args=args):
                code, _, err = run("ping", *args, check=False)
                self.assertEqual(code, 1)
                self.assertIn(named, err)
                self.assertEqual(len(err.strip().splitlines()), 1)

    def test_cyclones_own_complaints_come_in_our_one_line(self):
        for args, env, named in (
                (["--interface", "nope0"], {}, "nope0: does not match an available interface"),
                ([], {"CYCLONEDDS_URI": "garbage<<"}, "can't open configuration file garbage<<"),
                (["--interface", "lo"], {"CYCLONEDDS_URI": "<Bogus/>"}, "Bogus: unknown element")):
            with self.subTest(args=args, env=env):
                proc = subprocess.run([DCL_SLAM, "ping", "--robot", "0", "--duration", "1",
                                       "--domain", "54", *args], capture_output=True, text=True,
                                      timeout=60, env={**os.environ, **env})
                self.assertEqual(proc.returncode, 1)
                lines = proc.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, proc.stderr)
                self.assertTrue(lines[0].startswith("dcl-slam: error: DDS: "), proc.stderr)
                self.assertIn(named, lines[0])


class OutputFolders(unittest.TestCase):
    """Every command that writes an output folder: it is checked before the
    work, never mixes two runs, never replaces a folder of other files
    without --force, and a kill at any moment leaves it whole."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "ds")
        run("simulate", "--preset", "small-3", "--robots", "2", "--max-scans", "40", "--out",
            cls.dataset)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def commands(self, out):
        """Each command with a small job, writing into out."""
        ds = self.dataset
        return {
            "run": ["run", "--dataset", ds, "--out", out, "--max-frames", "20"],
            "simulate": ["simulate", "--preset", "small-3", "--robots", "1", "--max-scans", "2",
                         "--out", out],
            "odometry": ["odometry", "--dataset", ds, "--out", out, "--max-frames", "10"],
            "bench place": ["bench", "place", "--dataset", ds, "--out", out],
            "bench loops": ["bench", "loops", "--dataset", ds, "--out", out],
        }

    def snapshot(self, folder):
        """{relative path: bytes} of every file under folder (hidden ones too)."""
        files = {}
        for root, _, names in os.walk(folder):
            for name in names:
                full = os.path.join(root, name)
                with open(full, "rb") as f:
                    files[os.path.relpath(full, folder)] = f.read()
        return files

    def assertOneErrorLine(self, code, err, *fragments):
        self.assertNotEqual(code, 0)
        lines = err.strip().splitlines()
        self.assertEqual(len(lines), 1, err)
        self.assertTrue(lines[0].startswith("dcl-slam: error: "), err)
        for fragment in fragments:
            self.assertIn(fragment, lines[0])

    def test_a_folder_of_other_files_is_refused_unless_forced(self):
        for name in self.commands(""):
            with self.subTest(command=name):
                out = os.path.join(self.tmp.name, "theirs-" + name.replace(" ", "-"))
                os.makedirs(out)
                with open(os.path.join(out, "thesis.tex"), "w") as f:
                    f.write("three years of work")
                before = self.snapshot(out)
                code, _, err = run(*self.commands(out)[name], check=False)
                self.assertOneErrorLine(code, err, out, "--force")
                self.assertEqual(self.snapshot(out), before)
                run(*self.commands(out)[name], "--force")
                self.assertNotIn("thesis.tex", os.listdir(out))
                self.assertIn(".dcl-slam", os.listdir(out))

    def test_a_second_run_replaces_the_first_whole(self):
        for name in self.commands(""):
            with self.subTest(command=name):
                out = os.path.join(self.tmp.name, "twice-" + name.replace(" ", "-"))
                run(*self.commands(out)[name])
                with open(os.path.join(out, "left-by-the-first.txt"), "w") as f:
                    f.write("x")
                run(*self.commands(out)[name])
                self.assertNotIn("left-by-the-first.txt", os.listdir(out))
                beside = [f for f in os.listdir(self.tmp.name) if ".partial-" in f]
                self.assertEqual(beside, [])

    def test_an_output_place_that_cannot_be_written_fails_before_the_work(self):
        a_file = os.path.join(self.tmp.name, "a-file")
        with open(a_file, "w") as f:
            f.write("x")
        for name in self.commands(""):
            for out, fragment in ((a_file, "is a file, not a folder"),
                                  (os.path.join(a_file, "sub"), "cannot create"),
                                  ("/proc/dcl-slam-test/out", "cannot create")):
                with self.subTest(command=name, out=out):
                    start = time.monotonic()
                    code, _, err = run(*self.commands(out)[name], check=False)
                    self.assertOneErrorLine(code, err, fragment)
                    self.assertLess(time.monotonic() - start, 5.0)
        with open(a_file) as f:
            self.assertEqual(f.read(), "x")

    def test_the_dataset_inside_the_output_folder_is_refused(self):
        for name in ("run", "odometry", "bench place", "bench loops"):
            with self.subTest(command=name):
                code, _, err = run(*self.commands(self.tmp.name)[name], "--force", check=False)
                self.assertOneErrorLine(code, err, "lies in --out")
                self.assertTrue(os.path.exists(os.path.join(self.dataset, "dataset.yaml")))

    def test_an_interrupt_says_the_folder_keeps_what_it_held(self):
        # A run of 400 frames a robot, seconds of work even with its scans
        # cached, interrupted after 0.3 s (the class's 40 frames can be done by then).
        long = os.path.join(self.tmp.name, "long")
        run("simulate", "--preset", "small-3", "--robots", "2", "--max-scans", "400", "--out",
            long)
        out = os.path.join(self.tmp.name, "interrupted")
        args = ["run", "--dataset", long, "--out", out]
        run(*args, "--max-frames", "20")
        before = self.snapshot(out)
        proc = subprocess.Popen([DCL_SLAM, *args],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        self.assertEqual(proc.returncode, 128 + signal.SIGINT, err)
        self.assertIn(f"dcl-slam: interrupted before its outputs were written; {out} keeps "
                      "what it held", err)
        self.assertEqual(self.snapshot(out), before)

    def test_a_kill_at_any_moment_leaves_one_whole_run(self):
        out = os.path.join(self.tmp.name, "killed")
        args = ["run", "--dataset", self.dataset, "--out", out]
        run(*args, "--max-frames", "20")
        old = self.snapshot(out)
        start = time.monotonic()
        run(*args, "--max-frames", "30")
        new_files = set(self.snapshot(out))
        full = time.monotonic() - start
        run(*args, "--max-frames", "20")
        rng = random.Random(29)
        outcomes = set()
        for trial in range(10):
            # Spread over the run, the last ones in its final writes.
            delay = full * (trial / 10 + 0.1 * rng.random())
            proc = subprocess.Popen([DCL_SLAM, *args, "--max-frames", "30"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(delay)
            proc.kill()
            proc.wait()
            now = self.snapshot(out)
            if now == old:
                outcomes.add("untouched")
            else:
                self.assertEqual(set(now), new_files, f"trial {trial} after {delay:.2f} s")
                json.loads(now["metrics.json"])
                outcomes.add("new")
                run(*args, "--max-frames", "20")  # back to the old run
                old = self.snapshot(out)
        self.assertIn("untouched", outcomes)
        # What killed runs leave beside the folder goes with the next command.
        run(*args, "--max-frames", "20")
        self.assertEqual([f for f in os.listdir(self.tmp.name) if ".partial-" in f], [])


def tum_poses(path):
    """{stamp: (x, y, z)} of a TUM file."""
    with open(path) as f:
        rows = [line.split() for line in f if line.strip() and not line.startswith("#")]
    return {float(r[0]): tuple(float(v) for v in r[1:4]) for r in rows}


def steps(poses):
    """The distances between consecutive poses, in stamp order."""
    stamps = sorted(poses)
    return [math.dist(poses[a], poses[b]) for a, b in zip(stamps, stamps[1:])]


class ExternalFrontEnd(unittest.TestCase):
    """A swarm whose robots bring their own front-end (dataset.yaml's `odometry`):
    `simulate --odometry-drift` makes one from the ground truth, drifting, and
    `run`, `robot` and `odometry` take its poses instead of the built-in odometry."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "ds")
        run("simulate", "--preset", "small-3", "--robots", "2", "--max-scans", "200",
            "--odometry-drift", "1,0.01", "--out", cls.dataset)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def assertFollowsTheFrontEnd(self, folder, robot):
        """The robot's odometry (keyframes' T_odom_keyframe) moves as the
        front-end's file does between the same stamps."""
        front_end = tum_poses(os.path.join(self.dataset, "odometry", robot + ".tum"))
        odometry = tum_poses(os.path.join(folder, "odometry.tum"))
        self.assertGreater(len(odometry), 8, robot)
        for stamp in odometry:
            self.assertIn(round(stamp, 6), {round(t, 6) for t in front_end}, robot)
        kept = {t: front_end[min(front_end, key=lambda u: abs(u - t))] for t in odometry}
        for ours, theirs in zip(steps(odometry), steps(kept)):
            self.assertAlmostEqual(ours, theirs, delta=1e-3, msg=robot)

    def test_the_dataset_names_each_robots_front_end(self):
        with open(os.path.join(self.dataset, "dataset.yaml")) as f:
            text = f.read()
        for robot in ("a", "b"):
            self.assertIn(f"file: odometry/{robot}.tum", text)
            self.assertTrue(os.path.exists(os.path.join(self.dataset, "odometry", robot + ".tum")))

    def test_run_takes_their_poses(self):
        out = os.path.join(self.tmp.name, "run")
        _, stdout, _ = run("run", "--dataset", self.dataset, "--out", out, "--json")
        metrics = json.loads(stdout)
        for r in metrics["robots"]:
            self.assertFollowsTheFrontEnd(os.path.join(out, r["name"]), r["name"])
            self.assertLess(r["ate_rmse"], 1.0, r["name"])

    def test_odometry_and_robot_take_their_poses(self):
        out = os.path.join(self.tmp.name, "odometry")
        run("odometry", "--dataset", self.dataset, "--robot", "b", "--out", out, "--no-loops")
        self.assertFollowsTheFrontEnd(out, "b")
        out = os.path.join(self.tmp.name, "robot")
        run("robot", "--dataset", self.dataset, "--robot", "a", "--out", out, "--max-frames", "120",
            "--rate", "20", "--linger", "1", "--settle", "0", "--domain", "78", "--interface", "lo",
            "--swarm", f"ext-{os.getpid()}")
        self.assertFollowsTheFrontEnd(os.path.join(out, "a"), "a")

    def test_a_missing_front_end_file_is_named(self):
        broken = os.path.join(self.tmp.name, "broken")
        shutil.copytree(self.dataset, broken)
        os.remove(os.path.join(broken, "odometry", "b.tum"))
        code, _, err = run("run", "--dataset", broken, "--out", os.path.join(self.tmp.name, "x"),
                           check=False)
        self.assertNotEqual(code, 0)
        self.assertIn("b.tum", err)
        self.assertFalse(os.path.exists(os.path.join(self.tmp.name, "x")))


class Run(unittest.TestCase):
    """dcl-slam run: the small-3 campus, three robots over the simulated radio,
    the first 150 scans of each, twice: the outputs are complete and the
    same both times."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dataset = os.path.join(cls.tmp.name, "demo")
        run("simulate", "--preset", "small-3", "--out", cls.dataset)
        cls.outs = [os.path.join(cls.tmp.name, f"run{i}") for i in (1, 2)]
        cls.metrics = []
        for out, threads in zip(cls.outs, ("1", "2")):
            _, stdout, _ = run("run", "--dataset", cls.dataset, "--out", out, "--max-frames",
                               "150", "--threads", threads, "--json")
            cls.metrics.append(json.loads(stdout))

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_every_output_is_written(self):
        out = self.outs[0]
        for name in ("metrics.json", "report.html"):
            self.assertTrue(os.path.getsize(os.path.join(out, name)) > 0, name)
        for robot in ("a", "b", "c"):
            for name in ("trajectory.tum", "trajectory.kitti", "odometry.tum", "graph.g2o"):
                self.assertTrue(os.path.exists(os.path.join(out, robot, name)), robot + "/" + name)
            with open(os.path.join(out, robot, "trajectory.tum")) as f:
                rows = [line for line in f if line.strip() and not line.startswith("#")]
            self.assertGreater(len(rows), 0, robot)
            self.assertEqual(len(rows), next(r["keyframes"] for r in self.metrics[0]["robots"]
                                             if r["name"] == robot), robot)
        with open(os.path.join(out, "metrics.json")) as f:
            self.assertEqual(json.load(f), self.metrics[0])

    def test_the_map_holds_every_robot_in_its_colour(self):
        for out, metrics in zip(self.outs, self.metrics):
            Demo.check_maps(self, out, metrics)
            for r in metrics["robots"]:
                # Kept compactly: a VLP-16 keyframe's cloud in a few kilobytes.
                self.assertLess(r["map_cloud_bytes"], 20000 * r["keyframes"], r["name"])

    def test_metrics_name_every_robot_with_its_figures(self):
        robots = self.metrics[0]["robots"]
        self.assertEqual([r["name"] for r in robots], ["a", "b", "c"])
        for r in robots:
            self.assertEqual(r["frames"], 150)
            for field in ("ate_rmse", "ate_rmse_odometry_only", "bytes_sent", "bytes_received",
                          "inter_loops_accepted", "inter_loops_rejected", "counters"):
                self.assertIn(field, r)
            self.assertEqual(r["counters"]["descriptors_sent"], r["keyframes"])
        # Robot c barely moves in its first 15 s; a and b drive tens of metres.
        evaluated = [r for r in robots if r["ate_rmse"] is not None]
        self.assertGreaterEqual(len(evaluated), 2)
        for r in evaluated:
            self.assertLess(r["ate_rmse"], 1.0, r["name"])

    def test_a_run_without_a_map_leaves_no_map_of_an_earlier_run(self):
        out = os.path.join(self.tmp.name, "nomap")
        shutil.copytree(self.outs[0], out)
        with tempfile.NamedTemporaryFile("w", suffix=".yaml") as f:
            f.write("map: {voxel: 0}\n")
            f.flush()
            _, stdout, _ = run("--config", f.name, "run", "--dataset", self.dataset, "--out", out,
                               "--max-frames", "20", "--json")
        metrics = json.loads(stdout)
        self.assertEqual(metrics["map_points"], 0)
        for name in ("map.ply", "a/map.ply", "b/map.ply", "c/map.ply"):
            self.assertFalse(os.path.exists(os.path.join(out, name)), name)
        self.assertEqual(metrics["robots"][0]["frames"], 20)

    def test_robots_that_never_met_end_in_frames_of_their_own(self):
        # In their first 2 s the robots close no loop: each stays in its own
        # odometry frame, and the table says the maps are not joined (the whole
        # run, with loops, puts all three in a's).
        out = os.path.join(self.tmp.name, "apart")
        _, stdout, _ = run("run", "--dataset", self.dataset, "--out", out, "--max-frames", "20")
        self.assertIn("the robots end in 3 frames no loop joins: a | b | c", stdout)
        with open(os.path.join(out, "metrics.json")) as f:
            metrics = json.load(f)
        self.assertEqual([r["frame"] for r in metrics["robots"]], ["a", "b", "c"])

    def test_a_robot_that_leaves_keeps_what_it_held_and_the_others_play_on(self):
        out = os.path.join(self.tmp.name, "leave")
        _, stdout, _ = run("run", "--dataset", self.dataset, "--out", out, "--max-frames", "150",
                           "--leave", "b@6")
        self.assertIn("b left the swarm at 6 s", stdout)
        with open(os.path.join(out, "metrics.json")) as f:
            robots = {r["name"]: r for r in json.load(f)["robots"]}
        # 10 scans a second from the run's start: b plays 6 s of them, the others all 150.
        self.assertEqual(robots["b"]["frames"], 60)
        self.assertEqual(robots["b"]["left_at_s"], 6.0)
        for name in ("a", "c"):
            self.assertEqual(robots[name]["frames"], 150, name)
            self.assertIsNone(robots[name]["left_at_s"], name)
        with open(os.path.join(out, "b", "trajectory.tum")) as f:
            rows = [line for line in f if line.strip() and not line.startswith("#")]
        self.assertEqual(len(rows), robots["b"]["keyframes"])
        self.assertGreater(len(rows), 0)
        # bench bound names the robot that left, and the chi-square of the
        # graph of those that stayed, at the run and at its optimum.
        _, stdout, _ = run("bench", "bound", "--run", out, "--dataset", self.dataset, "--json")
        bound = json.loads(stdout)
        self.assertEqual(bound["left"], ["b"])
        self.assertEqual([r["left"] for r in bound["robots"]], [False, True, False])
        self.assertGreater(bound["cost_optimum_stayed"], 0.0)
        self.assertLessEqual(bound["cost_optimum_stayed"],
                             bound["cost_run_stayed"] * (1.0 + 1e-9))
        # Fewer factors than the whole graph's.
        self.assertLess(bound["cost_optimum_stayed"], bound["cost_optimum"])
        _, stdout, _ = run("bench", "bound", "--run", out, "--dataset", self.dataset)
        self.assertIn("b (left)", stdout)
        self.assertIn("Without the robots that left (b):", stdout)
        # A metrics.json that is not a run's is named.
        with open(os.path.join(out, "metrics.json"), "w") as f:
            f.write("[]")
        code, _, err = run("bench", "bound", "--run", out, "--dataset", self.dataset, check=False)
        self.assertEqual(code, 1)
        self.assertIn("metrics.json", err)
        self.assertIn("'robots'", err)
        # Without anyone leaving, every robot says so.
        for r in self.metrics[0]["robots"]:
            self.assertIsNone(r["left_at_s"], r["name"])

    def test_a_bad_leave_is_refused_before_anything_is_written(self):
        out = os.path.join(self.tmp.name, "badleave")
        for value, named in (("z@5", "no robot 'z' in the dataset (its robots: a, b, c)"),
                             ("b", "NAME@SECONDS"), ("b@-1", "'-1' is not a time"),
                             ("b@soon", "'soon' is not a time")):
            code, _, err = run("run", "--dataset", self.dataset, "--out", out, "--max-frames",
                               "20", "--leave", value, check=False)
            self.assertEqual(code, 1, value)
            self.assertIn(named, err, value)
            self.assertIn(value, err, value)
            self.assertFalse(os.path.exists(out), value)

    def test_a_negative_settle_is_refused_before_anything_is_written(self):
        out = os.path.join(self.tmp.name, "unsettled")
        for value in ("-1", "nan"):
            code, _, err = run("run", "--dataset", self.dataset, "--out", out, "--max-frames",
                               "20", "--settle", value, check=False)
            self.assertEqual(code, 1, value)
            self.assertIn("settle", err, value)
            self.assertFalse(os.path.exists(out), value)

    def test_one_or_two_threads_give_the_same_run(self):
        self.assertEqual(self.metrics[0], self.metrics[1])
        for robot in ("a", "b", "c"):
            with open(os.path.join(self.outs[0], robot, "graph.g2o")) as f1, \
                    open(os.path.join(self.outs[1], robot, "graph.g2o")) as f2:
                self.assertEqual(f1.read(), f2.read(), robot)
        for name in ("map.ply", "a/map.ply", "c/map.ply"):
            with open(os.path.join(self.outs[0], name), "rb") as f1, \
                    open(os.path.join(self.outs[1], name), "rb") as f2:
                self.assertEqual(f1.read(), f2.read(), name)


class LiveView(unittest.TestCase):
    """run --viz: the run served to Foxglove over the Foxglove WebSocket protocol,
    checked with Foxglove's own client (@foxglove/ws-protocol on Node.js, which
    scripts/setup --npm-prefix installs into the build)."""

    MODULES = os.environ.get("DCL_NODE_MODULES", "")

    def client(self, port, topic, count, junk=False, growing=False):
        env = dict(os.environ, JUNK="1" if junk else "0", GROWING="1" if growing else "0")
        return subprocess.Popen(
            ["node", os.path.join(os.path.dirname(__file__), "foxglove_client.js"),
             self.MODULES, str(port), topic, str(count)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)

    def test_foxglove_sees_every_robots_path_grow(self):
        self.assertTrue(os.path.isdir(os.path.join(self.MODULES, "@foxglove", "ws-protocol")),
                        "scripts/setup --npm-prefix BUILD/npm installs @foxglove/ws-protocol")
        with tempfile.TemporaryDirectory() as tmp:
            dataset = os.path.join(tmp, "ds")
            run("simulate", "--preset", "small-3", "--robots", "2", "--max-scans", "300",
                "--out", dataset)
            # Port 0: any free one; the run says which before it waits for a viewer.
            proc = subprocess.Popen(
                [DCL_SLAM, "run", "--dataset", dataset, "--out", os.path.join(tmp, "out"),
                 "--viz", "0", "--viz-wait", "60", "--json"],
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            self.addCleanup(lambda: proc.poll() is None and proc.kill())
            line = proc.stderr.readline()
            self.assertIn("live view: ws://127.0.0.1:", line)
            port = int(line.split("ws://127.0.0.1:")[1].split()[0])
            # One viewer that first sends junk, one per other channel watched;
            # the paths' viewers count a path only when it grew (the run sends
            # them at wall-clock times, which a loaded machine fills slowly).
            viewers = {"a": self.client(port, "/a/path", 6, junk=True, growing=True),
                       "b": self.client(port, "/b/path", 6, growing=True),
                       "scan": self.client(port, "/a/scan", 3),
                       "loops": self.client(port, "/b/loops", 2),
                       "map": self.client(port, "/a/map", 2)}
            got_all = {}
            for name, viewer in viewers.items():
                out, err = viewer.communicate(timeout=180)
                self.assertEqual(viewer.returncode, 0, err + out)
                got_all[name] = json.loads(out)
            rest, err = proc.communicate(timeout=180)
            self.assertEqual(proc.returncode, 0, err)
            metrics = json.loads(rest)
        scan, loops, whole = got_all.pop("scan"), got_all.pop("loops"), got_all.pop("map")
        # The whole map, thinned: more than a scan holds, and growing as the robot drives.
        self.assertEqual(whole["channel"]["schemaName"], "foxglove.PointCloud")
        self.assertEqual(len(whole["messages"]), 2)
        for m in whole["messages"]:
            self.assertEqual((m["fields"], m["frame_id"]), ("x:0:7,y:4:7,z:8:7", "map"))
        sizes = [m["points"] for m in whole["messages"]]
        self.assertGreater(sizes[0], 1000)
        self.assertGreaterEqual(sizes[1], sizes[0])
        self.assertGreater(sizes[1], max(m["points"] for m in scan["messages"]))
        self.assertEqual(scan["channel"]["schemaName"], "foxglove.PointCloud")
        for m in scan["messages"]:
            # Packed float x, y, z; a whole number of points, as many as a keyframe keeps.
            self.assertEqual(m["fields"], "x:0:7,y:4:7,z:8:7")
            self.assertEqual(m["points"], int(m["points"]))
            self.assertGreater(m["points"], 1000)
            self.assertEqual(m["frame_id"], "map")
        self.assertEqual(loops["channel"]["schemaName"], "foxglove.SceneUpdate")
        for m in loops["messages"]:
            self.assertEqual((m["frame_id"], m["line_type"]), ("map", 2))  # a LINE_LIST
            self.assertEqual(m["line_points"] % 2, 0)  # two ends a loop
        seen = got_all
        for name, got in seen.items():
            self.assertEqual(got["serverInfo"], "dcl-slam")
            self.assertEqual(got["channel"], {"topic": f"/{name}/path", "encoding": "json",
                                              "schemaName": "foxglove.PosesInFrame",
                                              "schemaIsJson": True})
            messages = got["messages"]
            self.assertGreaterEqual(len(messages), 6, name)
            stamps = [m["stamp"] for m in messages]
            self.assertEqual(stamps, sorted(stamps), name)
            self.assertLess(stamps[0], stamps[-1], name)
            self.assertTrue(all(m["frame_id"] == "map" for m in messages))
            # The path advances: more keyframes, and the newest one elsewhere.
            poses = [m["poses"] for m in messages]
            self.assertEqual(poses, sorted(set(poses)), name)  # each with more keyframes
            first, last = messages[0]["last"], messages[-1]["last"]
            self.assertGreater(math.dist((first["x"], first["y"]), (last["x"], last["y"])), 1.0)
        # The viewer's junk did not disturb the run.
        self.assertEqual([r["frames"] for r in metrics["robots"]], [300, 300])
