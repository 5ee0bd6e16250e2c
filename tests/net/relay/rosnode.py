"""Tiny rospy nodes the relay tests run as subprocesses (one rospy node per process).

    python rosnode.py pub TOPIC --count N [--rate HZ] [--latch] [--size BYTES] [--wait-subs]
    python rosnode.py sub TOPIC --count N [--type std_msgs/String]

``pub`` sends std_msgs/String "msg <i>" (padded to --size); ``sub`` receives raw bytes with
rospy.AnyMsg and prints each message's hex on its own line, then exits after --count.
"""

from __future__ import annotations

import argparse
import sys
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=["pub", "sub"])
    parser.add_argument("topic")
    parser.add_argument("--count", type=int, default=10)
    parser.add_argument("--rate", type=float, default=20.0)
    parser.add_argument("--latch", action="store_true")
    parser.add_argument("--size", type=int, default=0)
    parser.add_argument("--forever", action="store_true", help="pub: keep going after --count")
    parser.add_argument("--prefix", default="msg", help="pub: text before the index")
    parser.add_argument("--wait-subs", action="store_true", help="pub: publish only once someone is connected")
    args = parser.parse_args()

    import rospy
    from std_msgs.msg import String

    rospy.init_node(f"relay_test_{args.role}", anonymous=True, disable_signals=True)
    if args.role == "pub":
        pub = rospy.Publisher(args.topic, String, queue_size=100, latch=args.latch)
        print("ready", flush=True)
        while args.wait_subs and pub.get_num_connections() == 0 and not rospy.is_shutdown():
            time.sleep(0.01)
        i = 0
        while not rospy.is_shutdown() and (args.forever or i < args.count):
            pub.publish(String(data=f"{args.prefix} {i}".ljust(args.size, "x")))
            i += 1
            time.sleep(1.0 / args.rate)
        if args.latch:
            while not rospy.is_shutdown():
                time.sleep(0.5)
        else:
            time.sleep(0.5)
        return

    got: list[bytes] = []

    def on_msg(msg: rospy.AnyMsg) -> None:
        got.append(msg._buff)
        print(msg._buff.hex(), flush=True)

    rospy.Subscriber(args.topic, rospy.AnyMsg, on_msg, queue_size=1000)
    print("ready", flush=True)
    while len(got) < args.count and not rospy.is_shutdown():
        time.sleep(0.02)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
