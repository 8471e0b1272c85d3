"""Convert a nav_msgs/Odometry topic of a rosbag2 bag (sqlite3 or MCAP) into a TUM file: `t x y z qx qy qz qw` a line,
t the message's header stamp in UNIX seconds (what riverbench's `clock = "unix"` reads).

    python odometry_to_tum.py BAG TOPIC OUT.tum

Needs only the rosbags package (no ROS): run_stack.sh calls it on the bag it records, and a command component can call
it on the bench's own recording (its /ground_truth/odom, as tests/test_command_component.py does).
"""

from __future__ import annotations

import sys
from pathlib import Path

from rosbags.highlevel import AnyReader


def convert(bag: Path, topic: str, out: Path) -> int:
    """Write `topic`'s poses from `bag` to `out` as TUM lines in header-stamp order; the number of poses."""
    rows = []
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        if not connections:
            raise SystemExit(f"{bag}: no topic {topic} (has: {', '.join(sorted({c.topic for c in reader.connections}))})")
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            rows.append((msg.header.stamp.sec, msg.header.stamp.nanosec, p.x, p.y, p.z, q.x, q.y, q.z, q.w))
    rows.sort(key=lambda r: (r[0], r[1]))
    with open(out, "w") as handle:
        for sec, nsec, *pose in rows:
            handle.write(f"{sec}.{nsec:09d} " + " ".join(f"{v:.9f}" for v in pose) + "\n")
    return len(rows)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    print(convert(Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])), "poses")
