"""rospy nodes of dynaorb (import only under a ROS 1 Python: Debian's python3 / the .venv)."""
