"""Container recipe for the SLAM workload (Dockerfile.j2)."""
