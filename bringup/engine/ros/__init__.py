"""The ROS engine: the lockstep clock node, the participant host, the launcher and its run spec,
the FastDDS profile and the shared-memory cleanup."""
