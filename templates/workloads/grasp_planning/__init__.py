"""Container recipe for the grasp-planning workload (Dockerfile.j2)."""
