"""ROS 1 bags without ROS: dataset sequences written as bags (rosbags), bags
read back serially, frame by frame, for the runner (`dynaorb bag run`), and
bags written back as dataset folders (`dynaorb bag to-dataset`)."""

from dynaorb.ros.bag.read import BagProvider
from dynaorb.ros.bag.run import BagRunOptions, run_bag
from dynaorb.ros.bag.to_dataset import BagToDatasetOptions, bag_to_dataset
from dynaorb.ros.bag.write import BagWriteOptions, write_dataset_bag

__all__ = ["BagProvider", "BagRunOptions", "BagToDatasetOptions", "BagWriteOptions", "bag_to_dataset", "run_bag",
           "write_dataset_bag"]
