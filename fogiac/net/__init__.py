"""The edge's connection to its cloud nodes: the relay (``fogiac.net.relay``) and the VPN."""
