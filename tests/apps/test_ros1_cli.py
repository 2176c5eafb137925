"""End to end on ROS 1, as a ROS user runs it: Debian's `roscore`, two robots'
scans played from bags by `rosbag play`, two `dcl-slam robot --ros1`
processes (talking with each other over Cyclone DDS, domain 77, on
loopback), and a rospy node listening to what they publish."""
import json
import math
import os
import signal
import socket
import subprocess
import tempfile
import time
import unittest
import xmlrpc.client

DCL_SLAM = os.environ["DCL_SLAM"]
HERE = os.path.dirname(os.path.abspath(__file__))
PYTHON = "/usr/bin/python3"


def run(*args, timeout=300):
    proc = subprocess.run([DCL_SLAM, *args], capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise AssertionError(f"dcl-slam {' '.join(args)} failed: {proc.stderr}")
    return proc.stdout


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tum(path):
    with open(path) as f:
        return [[float(v) for v in line.split()] for line in f
                if line.strip() and not line.startswith("#")]


class Ros1Robot(unittest.TestCase):
    ROBOTS = ("a", "b")
    SCANS = 150

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        tmp = cls.tmp.name
        cls.dataset = os.path.join(tmp, "ds")
        run("simulate", "--preset", "small-3", "--robots", str(len(cls.ROBOTS)), "--max-scans",
            str(cls.SCANS), "--export", "bag", "--out", cls.dataset)
        port = free_port()
        cls.env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}",
                       ROS_HOSTNAME="127.0.0.1", ROS_HOME=os.path.join(tmp, "ros_home"),
                       ROS_LOG_DIR=os.path.join(tmp, "ros_log"))
        cls.roscore = subprocess.Popen(["roscore", "-p", str(port)], env=cls.env,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.time() + 60
        while True:
            try:
                with xmlrpc.client.ServerProxy(cls.env["ROS_MASTER_URI"]) as master:
                    master.getPid("/dcl_test")
                break
            except OSError:
                if time.time() > deadline or cls.roscore.poll() is not None:
                    raise AssertionError("roscore did not start")
                time.sleep(0.2)

    @classmethod
    def tearDownClass(cls):
        cls.roscore.send_signal(signal.SIGINT)
        try:
            cls.roscore.wait(timeout=30)
        except subprocess.TimeoutExpired:
            cls.roscore.kill()
        cls.tmp.cleanup()

    def spawn(self, args, **kw):
        proc = subprocess.Popen(args, env=self.env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, **kw)
        self.addCleanup(lambda: proc.poll() is None and proc.kill())
        return proc

    def stop(self, proc, timeout=60):
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=timeout)
        return out, err

    def test_two_live_robots_track_their_scans_and_publish_what_rviz_shows(self):
        out = os.path.join(self.tmp.name, "out")
        heard_file = os.path.join(self.tmp.name, "heard.json")
        listener = self.spawn([PYTHON, os.path.join(HERE, "ros1_listener.py"), heard_file,
                               *self.ROBOTS])
        self.assertEqual(listener.stdout.readline().strip(), "listening")
        # Robot a with the configuration's frames, b with its own.
        frames = {"a": ["map", "a/odom", "a/base_link"], "b": ["world", "b_odom", "b_base"]}
        robots = {}
        for i, r in enumerate(self.ROBOTS):
            robots[r] = self.spawn(
                [DCL_SLAM, "robot", "--ros1", "--robot", r, "--id", str(i), "--out", out,
                 "--points", f"/{r}/points", "--imu", f"/{r}/imu", "--domain", "77",
                 "--interface", "lo",
                 "--swarm", f"ros1-test-{os.getpid()}",
                 *(["--frame-ids", "world,b_odom,b_base,b_lidar"] if r == "b" else [])])
        for r, proc in robots.items():
            line = proc.stdout.readline()
            self.assertIn(f"robot {r}: reading /{r}/points on ROS 1", line)
        # Each robot's bag as its LiDAR driver would publish it, both at once.
        # roscpp connects each topic on its own: `-d 2` lets the robots'
        # subscriptions to /points and /imu both connect before the first
        # message goes out, so no scan arrives whose IMU reading was sent to
        # nobody.
        players = [subprocess.Popen(
            ["rosbag", "play", "--quiet", "-d", "2", "-r", "2",
             os.path.join(self.dataset, "bag", r, "scans.bag"),
             f"/points:=/{r}/points", f"/imu:=/{r}/imu", f"/ground_truth:=/{r}/ground_truth"],
            env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            for r in self.ROBOTS]
        for p in players:
            _, err = p.communicate(timeout=120)
            self.assertEqual(p.returncode, 0, err)
        time.sleep(2)
        reports, logs = {}, {}
        for r, proc in robots.items():
            _, err = self.stop(proc)
            logs[r] = err
            self.assertEqual(proc.returncode, 128 + signal.SIGINT, err)
            with open(os.path.join(out, r, "robot.json")) as f:
                reports[r] = json.load(f)
        time.sleep(1)  # the robots' last paths on their way to the listener
        self.stop(listener)
        with open(heard_file) as f:
            heard = json.load(f)

        for r in self.ROBOTS:
            report, counters = reports[r], reports[r]["counters"]
            # TCP on loopback: the scans arrive (roscpp drops the oldest of a
            # full queue of 5 if the robot is held up), none is unreadable, and
            # every scan the robot took went through the front-end.
            self.assertGreaterEqual(counters["scans_received"], self.SCANS * 0.9, r)
            self.assertEqual(counters["scans_refused"], 0, r)
            self.assertEqual(counters["messages_refused"], 0, r)
            self.assertEqual(report["frames"] + counters["scans_dropped"],
                             counters["scans_received"], r)
            self.assertGreater(report["keyframes"], 10, r)
            # The bag's IMU (sensor_msgs/Imu, one reading a scan) levels the
            # scans the robot took: each found its reading.
            self.assertGreaterEqual(counters["imu_received"], self.SCANS * 0.9, r)
            self.assertEqual(counters["imu_without_orientation"], 0, r)
            self.assertEqual(counters["scans_without_imu"], 0, f"{r}: {logs[r]}")
            # Stamped as the bag's clouds, against the bag's own ground truth.
            gt = os.path.join(self.tmp.name, f"gt_{r}.tum")
            run("convert", os.path.join(self.dataset, "bag", r, "scans.bag"), gt, "--topic",
                "/ground_truth")
            ate = json.loads(run("eval", "ate", "--gt", gt, "--est",
                                 os.path.join(out, r, "trajectory.tum"), "--format", "tum",
                                 "--align", "se3", "--json"))
            self.assertLess(ate["translation_m"]["rmse"], 0.3, r)

            # What rospy heard: types and md5 sums matched (rospy checks them),
            # frames as configured, and the last path is the trajectory written.
            h = heard["robots"][r]
            world, odom, base = frames[r]
            self.assertGreater(h["odometry"], 10, r)
            self.assertEqual(h["odometry_frame"], [world, base])
            self.assertEqual(h["path_frame"], world)
            trajectory = tum(os.path.join(out, r, "trajectory.tum"))
            self.assertEqual(len(h["path"]), len(trajectory), r)
            for (t, x, y, z), row in zip(h["path"], trajectory):
                self.assertAlmostEqual(t, row[0], places=3)
                self.assertLess(math.dist((x, y, z), row[1:4]), 1e-3, r)
            self.assertGreater(h["map_points"], 1000, r)
            self.assertEqual(h["map_frame"], world)
            self.assertEqual(h["map_fields"][:3], ["x", "y", "z"])
            # The whole map (every keyframe, coarser voxels) reaches further
            # than the local one (the last 30 keyframes).
            self.assertEqual(h["whole_map_frame"], world)
            self.assertGreater(h["whole_map_points"], 1000, r)
            self.assertIsNotNone(h["loop_markers"], r)
            self.assertIn([world, odom], heard["tf"])
            self.assertIn([odom, base], heard["tf"])
            # Its peer was heard over DDS.
            self.assertGreater(report["bytes_received"], 0, r)

    def test_without_a_master_it_says_so_in_time(self):
        env = dict(self.env, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}")
        config = os.path.join(self.tmp.name, "quick.yaml")
        with open(config, "w") as f:
            f.write("ros:\n  master_wait: 1\n")
        start = time.time()
        proc = subprocess.run(
            [DCL_SLAM, "--config", config, "robot", "--ros1", "--robot", "c", "--id",
             "2", "--out", os.path.join(self.tmp.name, "nomaster"), "--domain", "77",
             "--interface", "lo"], env=env, capture_output=True, text=True, timeout=60)
        self.assertNotEqual(proc.returncode, 0)
        self.assertIn("no master answers at http://127.0.0.1:", proc.stderr)
        self.assertLess(time.time() - start, 30)
        self.assertFalse(os.path.exists(os.path.join(self.tmp.name, "nomaster", "c")))


if __name__ == "__main__":
    unittest.main()
