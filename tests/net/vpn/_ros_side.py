"""A ROS 1 node for one side of the relay test: publishes one topic, echoes another.

Run as ``python _ros_side.py NAME PUB_TOPIC SUB_TOPIC``: publishes "NAME i" on PUB_TOPIC at
20 Hz and prints each message heard on SUB_TOPIC, one per line, until it is killed.
"""

from __future__ import annotations

import sys

import rospy
from std_msgs.msg import String


def main() -> None:
    name, pub_topic, sub_topic = sys.argv[1], sys.argv[2], sys.argv[3]
    rospy.init_node(f"relay_test_{name}")
    rospy.Subscriber(sub_topic, String, lambda msg: print(msg.data, flush=True))
    pub = rospy.Publisher(pub_topic, String, queue_size=10)
    rate, i = rospy.Rate(20), 0
    while not rospy.is_shutdown():
        pub.publish(String(data=f"{name} {i}"))
        i += 1
        rate.sleep()


if __name__ == "__main__":
    main()
