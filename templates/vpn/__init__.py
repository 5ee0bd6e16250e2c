"""OpenVPN files: the edge's Client VPN profile and an AWS-like server for tests and labs."""
