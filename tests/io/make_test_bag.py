#!/usr/bin/python3
"""Writes small ROS1 bags with known values for the dcl::io rosbag tests.

Run with Debian's interpreter (python3-rosbag, python3-sensor-msgs,
python3-nav-msgs): /usr/bin/python3 make_test_bag.py OUTPUT_FOLDER

Writes OUTPUT_FOLDER/clouds.bag, and the same messages in small chunks,
uncompressed (clouds_chunked.bag), bz2 (clouds_bz2.bag) and lz4
(clouds_lz4.bag). Every value below is mirrored by tests/io/test_rosbag.cpp;
change both together.
"""

import math
import os
import struct
import sys

import rosbag
from genpy import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2, PointField

I8, U8, I16, U16, I32, U32, F32, F64 = range(1, 9)
FORMATS = {I8: 'b', U8: 'B', I16: 'h', U16: 'H', I32: 'i', U32: 'I', F32: 'f', F64: 'd'}


def stamp(secs, nsecs):
    return Time(secs, nsecs)


def cloud(t, fields, point_step, rows, width, row_pad=0, big_endian=False):
    """A PointCloud2 whose rows hold the given points; fields are (name, offset, type)."""
    order = '>' if big_endian else '<'
    data = bytearray()
    for row in rows:
        for point in row:
            record = bytearray(point_step)
            for (name, offset, datatype), value in zip(fields, point):
                struct.pack_into(order + FORMATS[datatype], record, offset, value)
            data += record
        data += bytes(row_pad)
    msg = PointCloud2()
    msg.header.stamp = t
    msg.header.frame_id = 'lidar'
    msg.height = len(rows)
    msg.width = width
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in fields]
    msg.is_bigendian = big_endian
    msg.point_step = point_step
    msg.row_step = width * point_step + row_pad
    msg.data = bytes(data)
    msg.is_dense = True
    return msg


VELODYNE = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32), ('intensity', 16, F32),
            ('ring', 20, U16), ('time', 24, F32)]


def velodyne(k):
    """Message k: 4 points, x = k + j/4, y = -j/2, z = j/8, i = 10j + k, ring j, time j/1024."""
    points = [(k + j * 0.25, -j * 0.5, j * 0.125, 10.0 * j + k, j, j / 1024.0) for j in range(4)]
    return cloud(stamp(100, 500000000 + k * 100000000), VELODYNE, 32, [points], 4)


OUSTER = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32), ('intensity', 16, F32), ('t', 20, U32),
          ('reflectivity', 24, U16), ('ring', 26, U16), ('ambient', 28, U16), ('range', 32, U32)]


def ouster():
    """2 x 3 organised; point i = 3r + c: x = i, y = r, z = c, i = 100 + i, t = i ms in ns."""
    rows = [[(3 * r + c, r, c, 100.0 + 3 * r + c, (3 * r + c) * 1000000, 7, r, 9, 1234)
             for c in range(3)] for r in range(2)]
    return cloud(stamp(50, 0), OUSTER, 48, rows, 3)


OUSTER_U8_RING = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32), ('t', 12, U32), ('ring', 16, U8)]


def ouster_u8_ring():
    """1 x 2: x = y = z = j + 1, t = 5 ms * j, ring 60 + j."""
    points = [(j + 1.0, j + 1.0, j + 1.0, 5000000 * j, 60 + j) for j in range(2)]
    return cloud(stamp(51, 0), OUSTER_U8_RING, 17, [points], 2)


F64_BIG = [('x', 0, F64), ('y', 8, F64), ('z', 16, F64), ('intensity', 24, U8), ('ring', 25, U8)]


def f64_big_endian():
    """2 x 2 big-endian with 8 bytes of row padding: x = 1000.123456789 + i, y = -2.5 i,
    z = 0.001 i, intensity 200 + i, ring i."""
    rows = [[(1000.123456789 + 2 * r + c, -2.5 * (2 * r + c), 0.001 * (2 * r + c), 200 + 2 * r + c,
              2 * r + c) for c in range(2)] for r in range(2)]
    return cloud(stamp(60, 0), F64_BIG, 32, rows, 2, row_pad=8, big_endian=True)


HESAI = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32), ('intensity', 12, F32),
         ('timestamp', 16, F64), ('ring', 24, U16)]


def hesai():
    """Absolute FLOAT64 timestamps: stamp 1700000000.25 + j * 0.0005, 3 points x = j."""
    base = 1700000000.25
    points = [(float(j), 0.0, 0.0, 1.0, base + j * 0.0005, 31 - j) for j in range(3)]
    return cloud(stamp(1700000000, 250000000), HESAI, 26, [points], 3)


def with_nan():
    """3 points, the middle one with x = NaN."""
    fields = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32)]
    points = [(1.0, 2.0, 3.0), (math.nan, 0.0, 0.0), (4.0, 5.0, 6.0)]
    return cloud(stamp(70, 0), fields, 12, [points], 3)


XYZ = [('x', 0, F32), ('y', 4, F32), ('z', 8, F32)]


def corrupt(kind):
    """A small valid cloud, then broken as `kind` says."""
    msg = cloud(stamp(80, 0), XYZ, 16, [[(1.0, 2.0, 3.0), (4.0, 5.0, 6.0)]], 2)
    if kind == 'short_data':
        msg.data = msg.data[:20]
    elif kind == 'field_overrun':
        msg.fields[2].offset = 14
    elif kind == 'no_x':
        msg.fields = msg.fields[1:]
    elif kind == 'row_step':
        msg.row_step = 16
    elif kind == 'bad_datatype':
        msg.fields[0].datatype = 42
    return msg


def odometry(k):
    """Stamp 200 + k, position (k, 2k, 0.5), yaw 0.1 k."""
    msg = Odometry()
    msg.header.stamp = stamp(200 + k, 0)
    msg.header.frame_id = 'odom'
    msg.child_frame_id = 'base_link'
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = k, 2.0 * k, 0.5
    msg.pose.pose.orientation.z = math.sin(0.05 * k)
    msg.pose.pose.orientation.w = math.cos(0.05 * k)
    return msg


def pose(k):
    """Stamp 300.25 + k; a quaternion (0, 0, 0, 2) to be normalised; position (-k, 0, 1)."""
    msg = PoseStamped()
    msg.header.stamp = stamp(300 + k, 250000000)
    msg.pose.position.x, msg.pose.position.z = -k, 1.0
    msg.pose.orientation.w = 2.0
    return msg


def write(path, **options):
    with rosbag.Bag(path, 'w', **options) as bag:
        for k in range(3):
            msg = velodyne(k)
            bag.write('/velodyne_points', msg, msg.header.stamp)
        for topic, msg in [('/ouster/points', ouster()), ('/ouster/points_u8_ring', ouster_u8_ring()),
                           ('/f64_big_endian', f64_big_endian()), ('/hesai/points', hesai()),
                           ('/with_nan', with_nan())]:
            bag.write(topic, msg, msg.header.stamp)
        for kind in ['short_data', 'field_overrun', 'no_x', 'row_step', 'bad_datatype']:
            good = corrupt('none')
            bag.write('/corrupt/' + kind, good, good.header.stamp)
            bad = corrupt(kind)
            bag.write('/corrupt/' + kind, bad, stamp(81, 0))
        for k in range(3):
            msg = odometry(k)
            bag.write('/odom', msg, msg.header.stamp)
        for k in range(2):
            msg = pose(k)
            bag.write('pose', msg, msg.header.stamp)


def main():
    write(os.path.join(sys.argv[1], 'clouds.bag'))
    for name, compression in [('chunked', 'none'), ('bz2', 'bz2'), ('lz4', 'lz4')]:
        write(os.path.join(sys.argv[1], 'clouds_%s.bag' % name), compression=compression,
              chunk_threshold=512)


if __name__ == '__main__':
    main()
