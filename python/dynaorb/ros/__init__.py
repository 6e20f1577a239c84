"""ROS 1 side of dynaorb.

The rospy nodes (segmentation_server, trajectory_recorder) import only under a
ROS 1 Python (Debian's python3 / the .venv); :mod:`dynaorb.ros.bag` reads and
writes ROS 1 bags with rosbags and needs no ROS installation.
"""
