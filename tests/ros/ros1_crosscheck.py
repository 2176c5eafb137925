"""Cross-check of dcl-slam's ROS 1 serialisation against ROS 1's own: genpy,
with the message classes of Debian's python3-*-msgs (ROS 1 Noetic's).

Usage: python3 ros1_crosscheck.py DIR

DIR holds, for each NAME, NAME.type (the message type, e.g. nav_msgs/Odometry),
NAME.ros1 (the bytes we wrote) and NAME.json (the values, every field named as
in the ROS 1 definition; a time or a duration as {"secs": s, "nsecs": ns}, a
uint8[] as a list of numbers). For each NAME, genpy reads NAME.ros1, and its
writer writes the values of NAME.json to NAME.genpy.ros1. Prints one JSON
object: for each NAME, the type's name, MD5 sum and full definition as genpy
holds them, and the values genpy read from our bytes, in the form of NAME.json.
Exits 1 naming the file when genpy cannot read our bytes or leaves some unread.
"""
import io
import json
import os
import sys

import genmsg.msgs
import genpy
import genpy.message


def to_json(value):
    """A genpy value in the form of NAME.json."""
    if isinstance(value, genpy.Message):
        return {slot: to_json(getattr(value, slot)) for slot in value.__slots__}
    if isinstance(value, (genpy.Time, genpy.Duration)):
        return {"secs": value.secs, "nsecs": value.nsecs}
    if isinstance(value, bytes):  # uint8[]
        return list(value)
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    return value


def from_json(slot_type, value):
    """A genpy value of `slot_type` from its form in NAME.json; every field required."""
    base, is_array, _ = genmsg.msgs.parse_type(slot_type)
    if is_array:
        if base == "uint8":
            return bytes(value)
        return [from_json(base, v) for v in value]
    if base == "time":
        return genpy.Time(value["secs"], value["nsecs"])
    if base == "duration":
        return genpy.Duration(value["secs"], value["nsecs"])
    if "/" not in base:
        return value
    message = genpy.message.get_message_class(base)()
    if set(value) != set(message.__slots__):
        raise ValueError(f"{base}: fields {sorted(value)}, not {sorted(message.__slots__)}")
    for slot, slot_type in zip(message.__slots__, message._slot_types):
        setattr(message, slot, from_json(slot_type, value[slot]))
    return message


def serialise(message):
    buffer = io.BytesIO()
    message.serialize(buffer)
    return buffer.getvalue()


def check(folder, name):
    with open(os.path.join(folder, name + ".type")) as f:
        cls = genpy.message.get_message_class(f.read().strip())
    with open(os.path.join(folder, name + ".ros1"), "rb") as f:
        ours = f.read()
    read = cls()
    try:
        read.deserialize(ours)
    except genpy.DeserializationError as e:
        raise ValueError(f"{name}.ros1: genpy cannot read it: {e}") from e
    # genpy does not say where it stopped; what it read is as long as what it writes.
    if len(serialise(read)) != len(ours):
        raise ValueError(f"{name}.ros1: {len(ours)} bytes, genpy read {len(serialise(read))}")
    with open(os.path.join(folder, name + ".json")) as f:
        values = json.load(f)
    with open(os.path.join(folder, name + ".genpy.ros1"), "wb") as f:
        f.write(serialise(from_json(cls._type, values)))
    return {"type": cls._type, "md5sum": cls._md5sum, "definition": cls._full_text,
            "read": to_json(read)}


def main():
    if len(sys.argv) != 2:
        print("usage: python3 ros1_crosscheck.py DIR", file=sys.stderr)
        return 2
    folder = sys.argv[1]
    names = sorted(f[: -len(".type")] for f in os.listdir(folder) if f.endswith(".type"))
    if not names:
        print(f"no NAME.type in {folder}", file=sys.stderr)
        return 1
    try:
        out = {name: check(folder, name) for name in names}
    except (ValueError, KeyError, TypeError, genpy.SerializationError) as e:
        print(e, file=sys.stderr)
        return 1
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
