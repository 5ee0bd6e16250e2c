"""Zenoh: how ROS 2 topics cross between the robot and the cloud hosts (rmw_zenoh's own way).

One router per cloud host listens with mutual TLS on the address the edge reaches; its access
control allows exactly the manifest's topics in their direction and denies everything else. The
edge router dials every cloud router (it never listens beyond loopback), so it works through
Client VPN's source NAT and home NAT; the robot's rmw_zenoh nodes (or zenoh-bridge-ros2dds for
DDS robots) connect to it. Modules: ``middleware`` (the registry entry), ``config`` (pure
rendering of router configs), ``tls`` (one certificate per host from fogiac's CA), ``router``
(a router process for hosts without ``zenohd``; a fleet's follows its fleet file), ``gate`` (a fleet's
router: a TLS gate that admits a robot by its certificate, and a router per robot behind it), ``monitor`` (latency
and throughput topics), ``fleet`` (a fleet's shared request/reply node: each reply to the robot that asked),
``deploy`` (what ``up`` runs where, a fleet's files and processes included).
"""

from fogiac.middlewares import MiddlewareEntry

ENTRY = MiddlewareEntry(name="zenoh", middleware="fogiac.net.zenoh.middleware:ZENOH",
                        deployment="fogiac.net.zenoh.deploy:DEPLOYMENT")
