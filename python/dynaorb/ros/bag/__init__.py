"""ROS 1 bags without ROS: dataset sequences written as bags (rosbags), and
bags read back serially, frame by frame, for the runner (`dynaorb bag run`)."""

from dynaorb.ros.bag.read import BagProvider
from dynaorb.ros.bag.run import BagRunOptions, run_bag
from dynaorb.ros.bag.write import BagWriteOptions, write_dataset_bag

__all__ = ["BagProvider", "BagRunOptions", "BagWriteOptions", "run_bag", "write_dataset_bag"]
