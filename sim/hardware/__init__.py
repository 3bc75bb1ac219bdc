"""The hardware bridge: real robots and motion capture on ROS 2 in the simulator's place
(docs/hardware.md). ``world`` and ``safety`` are pure Python; ``ros_link`` alone imports rclpy (the
``tlfleet[ros2]`` extra) and ``process`` imports it only when the bridge runs."""
