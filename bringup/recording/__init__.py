"""Recording: rosbag2 MCAP bags written and read without rclpy, the recorder process of a local
run, and the visualisation messages recorded with every run."""
