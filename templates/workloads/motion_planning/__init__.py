"""Container recipe for the motion-planning workload (Dockerfile.j2)."""
