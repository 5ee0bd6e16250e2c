"""rospy publisher / subscriber for the relay benchmark (one node per process).

    node.py pub TOPIC --size BYTES --rate HZ --duration S   (rate 0: as fast as it can)
    node.py sub TOPIC --duration S                          prints one JSON summary line

Messages are sensor_msgs/CompressedImage: header.stamp is set at publish time, so the
subscriber's latency is receive time minus stamp (same machine, same clock).
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=["pub", "sub"])
    parser.add_argument("topic")
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--settle", type=float, default=1.5)
    args = parser.parse_args()

    import rospy
    from sensor_msgs.msg import CompressedImage

    rospy.init_node(f"bench_{args.role}", anonymous=True, disable_signals=True)
    if args.role == "pub":
        pub = rospy.Publisher(args.topic, CompressedImage, queue_size=4)
        msg = CompressedImage(format="raw", data=bytes(args.size))
        while pub.get_num_connections() == 0 and not rospy.is_shutdown():
            time.sleep(0.05)
        time.sleep(args.settle)  # let the far side's subscriber finish connecting
        print("go", flush=True)
        end = time.monotonic() + args.duration
        period = 1.0 / args.rate if args.rate else 0.0
        seq = 0
        while time.monotonic() < end:
            msg.header.seq = seq
            msg.header.stamp = rospy.Time.now()
            pub.publish(msg)
            seq += 1
            if period:
                time.sleep(period)
        time.sleep(1.0)
        return

    arrivals: list[tuple[float, float, int, int]] = []  # recv time, latency s, bytes, seq

    def on_msg(msg: CompressedImage) -> None:
        now = rospy.Time.now()
        arrivals.append((time.monotonic(), (now - msg.header.stamp).to_sec(), len(msg.data), msg.header.seq))

    rospy.Subscriber(args.topic, CompressedImage, on_msg, queue_size=8, buff_size=64 * 1024 * 1024,
                     tcp_nodelay=True)
    print("ready", flush=True)
    while not arrivals and not rospy.is_shutdown():
        time.sleep(0.01)
    time.sleep(args.duration)
    print(json.dumps({"arrivals": arrivals}), flush=True)


if __name__ == "__main__":
    main()
