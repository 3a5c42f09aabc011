"""Deployment files: Docker Compose projects for one container per process of a ROS run."""
