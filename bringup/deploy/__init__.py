"""Deployment: Docker Compose projects (one container per process of a ROS run), the images they
run, a podman driver for them and the network impairment of their interfaces."""
