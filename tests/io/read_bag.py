#!/usr/bin/python3
"""Prints what Debian's own rosbag reads from a bag, for the dcl::io bag-writer tests.

Run with Debian's interpreter (python3-rosbag): /usr/bin/python3 read_bag.py BAG

One line per message, in bag order:
  cloud TOPIC STAMP WIDTH FIELDS x0 y0 z0 i0 ring0 time0   (the last point's values)
  odom TOPIC STAMP FRAME CHILD x y z qx qy qz qw
Messages are decoded from the definitions stored in the bag (genpy), so a wrong
definition or serialisation fails here.
"""
import struct
import sys

import rosbag


def cloud_line(topic, msg):
    names = ",".join(f"{f.name}:{f.offset}:{f.datatype}" for f in msg.fields)
    last = msg.data[(msg.width - 1) * msg.point_step:msg.width * msg.point_step]
    x, y, z, i, ring, time = struct.unpack("<ffffHxxf", last)
    stamp = msg.header.stamp.to_sec()
    return f"cloud {topic} {stamp:.9f} {msg.width} {names} {x!r} {y!r} {z!r} {i!r} {ring} {time!r}"


def odom_line(topic, msg):
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    stamp = msg.header.stamp.to_sec()
    return (f"odom {topic} {stamp:.9f} {msg.header.frame_id} {msg.child_frame_id} "
            f"{p.x!r} {p.y!r} {p.z!r} {q.x!r} {q.y!r} {q.z!r} {q.w!r}")


def main():
    with rosbag.Bag(sys.argv[1]) as bag:
        for topic, msg, _ in bag.read_messages():
            if msg._type == "sensor_msgs/PointCloud2":
                print(cloud_line(topic, msg))
            elif msg._type == "nav_msgs/Odometry":
                print(odom_line(topic, msg))
            else:
                print(f"other {topic} {msg._type}")


if __name__ == "__main__":
    main()
