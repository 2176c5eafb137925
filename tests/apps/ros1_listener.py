"""A ROS 1 node of rospy (ROS 1's own Python client) that listens to live
robots' topics until SIGINT or SIGTERM, then writes what it heard as JSON.

Usage: ros1_listener.py OUT.json ROBOT...   (ROS_MASTER_URI set)

For each robot: its odometry messages, the last path, the last local and
whole maps' sizes and frames, the last loop markers; and every tf edge seen."""
import json
import signal
import sys
import threading

import rospy
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import PointCloud2
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray


def stamp(header):
    return header.stamp.to_sec()


def main():
    out, robots = sys.argv[1], sys.argv[2:]
    heard = {r: {"odometry": 0, "odometry_frame": None, "path": [], "path_frame": None,
                 "map_points": 0, "map_frame": None, "map_fields": [], "loop_markers": None,
                 "whole_map_points": 0, "whole_map_frame": None}
             for r in robots}
    tf_edges = set()
    lock = threading.Lock()
    done = threading.Event()

    def on_odometry(robot, m):
        with lock:
            heard[robot]["odometry"] += 1
            heard[robot]["odometry_frame"] = [m.header.frame_id, m.child_frame_id]

    def on_path(robot, m):
        with lock:
            heard[robot]["path_frame"] = m.header.frame_id
            heard[robot]["path"] = [[stamp(p.header), p.pose.position.x, p.pose.position.y,
                                     p.pose.position.z] for p in m.poses]

    def on_map(robot, m):
        with lock:
            heard[robot]["map_points"] = m.width * m.height
            heard[robot]["map_frame"] = m.header.frame_id
            heard[robot]["map_fields"] = [f.name for f in m.fields]

    def on_whole_map(robot, m):
        with lock:
            heard[robot]["whole_map_points"] = m.width * m.height
            heard[robot]["whole_map_frame"] = m.header.frame_id

    def on_loops(robot, m):
        with lock:
            heard[robot]["loop_markers"] = [[k.ns, k.action, len(k.points)] for k in m.markers]

    def on_tf(m):
        with lock:
            for t in m.transforms:
                tf_edges.add((t.header.frame_id, t.child_frame_id))

    rospy.init_node("dcl_test_listener", anonymous=True, disable_signals=True)
    for r in robots:
        rospy.Subscriber(f"/{r}/odometry", Odometry, lambda m, r=r: on_odometry(r, m))
        rospy.Subscriber(f"/{r}/path", Path, lambda m, r=r: on_path(r, m))
        rospy.Subscriber(f"/{r}/local_map", PointCloud2, lambda m, r=r: on_map(r, m))
        rospy.Subscriber(f"/{r}/loops", MarkerArray, lambda m, r=r: on_loops(r, m))
        rospy.Subscriber(f"/{r}/map", PointCloud2, lambda m, r=r: on_whole_map(r, m))
    rospy.Subscriber("/tf", TFMessage, on_tf)
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    print("listening", flush=True)
    while not done.wait(0.1):
        pass
    with lock:
        result = {"robots": heard, "tf": sorted(list(e) for e in tf_edges)}
    with open(out, "w") as f:
        json.dump(result, f)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
