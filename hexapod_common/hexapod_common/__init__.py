"""Shared node conventions, message conversions, rosbag2 record/replay and the offline replay harness."""
