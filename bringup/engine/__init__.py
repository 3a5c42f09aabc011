"""Engines that drive the participants in lockstep: the contract both engines apply, the local
(in-process) engine, the lockstep wire rules and per-step checkpoints; ``ros/`` holds the ROS engine."""
