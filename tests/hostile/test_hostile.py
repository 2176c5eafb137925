"""Every reader of outside data, through the commands a user runs, against
generated bad inputs: empty, cut short, bytes changed at random, binary
garbage where text belongs, a folder where a file belongs, a file that is
not there.

Each case runs in its own sandbox under a time and memory limit and must
end with exit 0 (damage that still reads) or with one line on stderr that
starts `dcl-slam: error:` and shows no raw control bytes; never a signal, a
hang or a runaway allocation. Nothing outside the command's output may be
created or changed, and an output that was there before a failed command is
still there, unchanged. Inputs that cannot be right (empty, garbage, a
folder, missing) must fail.
"""
import os
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import unittest

DCL_SLAM = os.environ["DCL_SLAM"]
DATA = os.environ["DCL_DATA_DIR"]
SOURCE = os.environ["DCL_SOURCE_DIR"]

SECONDS = 60                # CPU seconds a case may use
MEMORY = 4 << 30            # bytes of address space a case may map
RANDOM_COPIES = 6           # randomly damaged copies of each input
OLD_OUTPUT = b"an output of an earlier command\n"


def limits():
    resource.setrlimit(resource.RLIMIT_CPU, (SECONDS, SECONDS))
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


def snapshot(folder, skip=()):
    """{path: (mtime, bytes)} of every file under folder, but those in or under `skip`."""
    files = {}
    for root, dirs, names in os.walk(folder):
        dirs[:] = [d for d in dirs if os.path.join(root, d) not in skip]
        for name in names:
            path = os.path.join(root, name)
            if path not in skip:
                with open(path, "rb") as f:
                    files[path] = (os.path.getmtime(path), f.read())
    return files


def variants(name, original, rng):
    """(label, bytes or None for a folder, must_fail) variants of a good input."""
    yield "empty", b"", True
    yield "folder", None, True
    # Raw float32 records (KITTI .bin) have no header: any 16 bytes are a point.
    yield "garbage", bytes(rng.getrandbits(8) for _ in range(4096)), not name.endswith(".bin")
    yield "half", original[: len(original) // 2], False
    yield "one byte short", original[:-1], False
    for k in range(RANDOM_COPIES):
        damaged = bytearray(original)
        for _ in range(min(50, max(1, len(damaged) // 20))):
            damaged[rng.randrange(len(damaged))] = rng.getrandbits(8)
        yield f"damaged {k}", bytes(damaged), False


class Hostile(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.good = os.path.join(cls.tmp.name, "good")
        os.makedirs(cls.good)
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "tests", "io", "make_test_bag.py"),
                        cls.good], check=True)
        subprocess.run([DCL_SLAM, "simulate", "--preset", "small-3", "--robots", "2",
                        "--max-scans", "4", "--odometry-drift", "1,0.01", "--out",
                        os.path.join(cls.good, "dataset")],
                       check=True, capture_output=True)
        subprocess.run([DCL_SLAM, "simulate", "--preset", "small-3", "--robots", "1",
                        "--max-scans", "2", "--export", "mcap", "--out",
                        os.path.join(cls.good, "mcap_dataset")],
                       check=True, capture_output=True)
        subprocess.run([DCL_SLAM, "convert",
                        os.path.join(DATA, "lidar_scans", "kitti_00", "velodyne", "000000.bin"),
                        os.path.join(cls.good, "scan.ply")], check=True, capture_output=True)
        dump = subprocess.run([DCL_SLAM, "config", "--dump"], check=True, capture_output=True)
        with open(os.path.join(cls.good, "config.yaml"), "wb") as f:
            f.write(dump.stdout)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()
        print(f"\nhostile inputs: {cls.outcomes['read']} read, {cls.outcomes['refused']} refused "
              "with one error line, none crashed, hung or wrote outside its output",
              file=sys.stderr)

    outcomes = {"read": 0, "refused": 0}

    def check(self, name, original, commands):
        """Runs every command on every variant of `original` (bytes).

        commands: label -> function(input path, output path) -> argv; the
        input is written at its place in a fresh sandbox, the output path
        (a file or a folder) is where the command may write."""
        rng = random.Random(name)
        for label, content, must_fail in variants(name, original, rng):
            for command, argv_of in commands.items():
                with self.subTest(input=name, variant=label, command=command):
                    self.run_case(name, content, must_fail, argv_of)

    def run_case(self, name, content, must_fail, argv_of):
        with tempfile.TemporaryDirectory(dir=self.tmp.name) as sandbox:
            cwd = os.path.join(sandbox, "cwd")
            os.makedirs(cwd)
            path = os.path.join(sandbox, name)
            if os.path.dirname(name):  # an input inside a folder (a dataset): copy it all
                top = name.split(os.sep)[0]
                shutil.copytree(os.path.join(self.good, top), os.path.join(sandbox, top))
            if content is None:
                if os.path.exists(path):
                    os.remove(path)
                os.makedirs(path)
            else:
                with open(path, "wb") as f:
                    f.write(content)
            out = os.path.join(sandbox, "out")
            argv = argv_of(path, out)
            # What the command may write: OUT itself (a folder) or OUT.ext files. Each
            # holds an earlier output first, which a failed command must leave alone.
            outputs = [a for a in argv if a == out or a.startswith(out + ".")]
            for o in outputs:
                if o == out:
                    os.makedirs(out)
                    with open(os.path.join(out, ".dcl-slam"), "wb") as f:
                        f.write(OLD_OUTPUT)
                    with open(os.path.join(out, "metrics.json"), "wb") as f:
                        f.write(OLD_OUTPUT)
                else:
                    with open(o, "wb") as f:
                        f.write(OLD_OUTPUT)
            before = snapshot(sandbox, skip=outputs)
            earlier = {o: snapshot(o) if o == out else self.read(o) for o in outputs}
            proc = subprocess.run([DCL_SLAM, *argv], cwd=cwd, capture_output=True,
                                  timeout=3 * SECONDS, preexec_fn=limits)
            err = proc.stderr.decode("utf-8", "replace")
            self.assertGreaterEqual(proc.returncode, 0, f"killed by signal: {err}")
            if proc.returncode != 0:
                errors = [line for line in err.splitlines() if line.startswith("dcl-slam: error: ")]
                self.assertEqual(len(errors), 1, err)
                self.assertTrue(err.rstrip("\n").splitlines()[-1].startswith("dcl-slam: error: "),
                                err)
                self.assertFalse(any(ord(c) < 0x20 and c not in "\n\t" for c in err), err)
                for o, old in earlier.items():
                    now = snapshot(o) if o == out else self.read(o)
                    self.assertEqual(now, old, f"{o}: a failed command changed an earlier output")
            Hostile.outcomes["read" if proc.returncode == 0 else "refused"] += 1
            if proc.returncode == 0 and must_fail:
                self.fail(f"exit 0 on an input that cannot be right: {proc.stdout[-300:]}")
            after = snapshot(sandbox, skip=outputs)
            self.assertEqual(sorted(after), sorted(before), "files outside the output changed")
            for p in before:
                self.assertEqual(after[p], before[p], f"{p} changed")
            self.assertEqual(os.listdir(cwd), [], "wrote into the working folder")

    # ---- the readers ------------------------------------------------------------------

    def read(self, *parts):
        with open(os.path.join(*parts), "rb") as f:
            return f.read()

    def test_tum_poses(self):
        gt = os.path.join(DATA, "trajectories", "evo", "freiburg1_xyz-groundtruth.txt")
        self.check("est.tum", self.read(DATA, "trajectories", "evo", "freiburg1_xyz-rgbdslam.txt"), {
            "eval ate": lambda i, o: ["eval", "ate", "--gt", gt, "--est", i, "--align", "se3"],
            "eval rpe": lambda i, o: ["eval", "rpe", "--gt", i, "--est", gt],
            "convert": lambda i, o: ["convert", i, o + ".kitti", "--from", "tum", "--to", "kitti",
                                     "--out-times", o + ".times"],
        })

    def test_kitti_poses(self):
        times = os.path.join(DATA, "trajectories", "evo", "KITTI_00_gt_times.txt")
        self.check("poses.txt", self.read(DATA, "trajectories", "evo", "KITTI_00_ORB.txt"), {
            "convert": lambda i, o: ["convert", i, o + ".tum", "--from", "kitti", "--times",
                                     times],
        })

    def test_kitti_times(self):
        poses = os.path.join(DATA, "trajectories", "evo", "KITTI_00_ORB.txt")
        self.check("times.txt", self.read(DATA, "trajectories", "evo", "KITTI_00_gt_times.txt"), {
            "convert": lambda i, o: ["convert", poses, o + ".tum", "--from", "kitti", "--times",
                                     i],
        })

    def test_g2o_graphs(self):
        self.check("graph.g2o", self.read(DATA, "pose_graphs", "3d", "tinyGrid3D.g2o"), {
            "pgo": lambda i, o: ["pgo", "--g2o", i, "--out", o + ".g2o"],
            "pgo 2d": lambda i, o: ["pgo", "--g2o", i, "--robots", "2"],
            "pcm": lambda i, o: ["pcm", "--graph", i],
        })

    def test_point_clouds(self):
        for name, original in (
                ("scan.pcd", self.read(DATA, "lidar_scans", "hdl_outdoor_pair_fast_gicp",
                                       "251370668.pcd")),
                ("scan.ply", self.read(self.good, "scan.ply")),
                ("scan.bin", self.read(DATA, "lidar_scans", "kitti_00", "velodyne",
                                       "000001.bin"))):
            self.check(name, original, {
                "convert": lambda i, o: ["convert", i, o + ".pcd"],
            })

    def test_ros1_bags(self):
        for name, original in (("clouds.bag", self.read(self.good, "clouds_lz4.bag")),
                               ("ground_truth.bag", self.read(DATA, "rosbags",
                                                              "evo_ROS_example.bag"))):
            self.check(name, original, {
                "poses": lambda i, o: ["convert", i, o + ".tum", "--topic",
                                       "/groundtruth" if "ground" in i else "/odom"],
                "clouds": lambda i, o: ["convert", i, o, "--topic", "/velodyne_points"],
            })

    def test_ros2_bags(self):
        found = [os.path.join(d, f) for d, _, fs in os.walk(os.path.join(self.good, "mcap_dataset"))
                 for f in fs if f.endswith(".mcap")]
        self.assertEqual(len(found), 1)
        with open(found[0], "rb") as f:
            original = f.read()
        self.check("scans.mcap", original, {
            "poses": lambda i, o: ["convert", i, o + ".tum", "--topic", "/ground_truth"],
            "clouds": lambda i, o: ["convert", i, o, "--topic", "/points"],
        })

    def test_datasets(self):
        folder = lambda i: os.path.join(i.split(os.sep + "dataset" + os.sep)[0], "dataset")
        commands = {
            "run": lambda i, o: ["run", "--dataset", folder(i), "--out", o],
            "odometry": lambda i, o: ["odometry", "--dataset", folder(i), "--robot", "b",
                                      "--out", o],
            "bench place": lambda i, o: ["bench", "place", "--dataset", folder(i), "--out", o],
            "bench loops": lambda i, o: ["bench", "loops", "--dataset", folder(i), "--out", o],
        }
        for name in (os.path.join("dataset", "dataset.yaml"),
                     os.path.join("dataset", "ground_truth", "b.tum")):
            self.check(name, self.read(self.good, name), commands)
        # A robot's own front-end: read by what runs its odometry (the
        # benchmarks of place recognition and loops take the ground truth).
        name = os.path.join("dataset", "odometry", "b.tum")
        self.check(name, self.read(self.good, name),
                   {k: commands[k] for k in ("run", "odometry")})

    def test_configs(self):
        dataset = os.path.join(self.good, "dataset")
        self.check("config.yaml", self.read(self.good, "config.yaml"), {
            "config": lambda i, o: ["config", "--dump", "--config", i],
            "run": lambda i, o: ["--config", i, "run", "--dataset", dataset, "--out", o],
        })


if __name__ == "__main__":
    unittest.main()
