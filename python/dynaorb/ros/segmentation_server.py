"""segmentation_server: semantic labels for the SLAM node, as a service and a topic.

Service     segment (dynaorb/Segment): image in; mono8 label image (header of
            the request), class names and movable class ids out.
Topic mode  subscribes image (sensor_msgs/Image) and publishes labels (mono8,
            same header) from a worker thread that always takes the newest
            image: a slow network drops frames here, never in the SLAM node,
            which propagates the last labels it got. ~image_transport
            compressed: image_transport's image/compressed (jpeg, png;
            sensor_msgs/CompressedImage) instead, as dynaorb_node reads it.
Parameters  ~model (file or catalog name, default the default model),
            ~threads (2), ~mode (service | topic | both, default both),
            ~image_transport (raw | compressed, default raw),
            ~nice (10, 0-19): the whole node runs this much below the
            SLAM node's priority, so tracking gets a busy machine's cores
            first and the network what is left.
            ~labels and ~movable_ids are set once the model is loaded; the
            labels topic is advertised before (see __init__).
"""
from __future__ import annotations

import threading

import cv2
import numpy as np
import rospy
from cv_bridge import CvBridge, CvBridgeError
from sensor_msgs.msg import CompressedImage, Image

from dynaorb.segmentation import Segmenter, resolve_model
from dynaorb.segmentation.priority import DEFAULT_NICE, check_nice, lower_process_priority
from dynaorb.srv import Segment, SegmentResponse


class SegmentationServer:
    def __init__(self):
        model = rospy.get_param("~model", "") or None
        threads = int(rospy.get_param("~threads", 2))
        mode = rospy.get_param("~mode", "both")
        if mode not in ("service", "topic", "both"):
            raise ValueError(f"~mode {mode!r} is not service, topic or both")
        transport = rospy.get_param("~image_transport", "raw")
        if transport not in ("raw", "compressed"):
            raise ValueError(f"~image_transport {transport!r} is not raw or compressed")
        nice = check_nice(rospy.get_param("~nice", DEFAULT_NICE), "~nice")
        refused = lower_process_priority(nice)  # before the network starts its threads
        if refused:
            rospy.logwarn("segmentation_server: keeps its priority (nice %d refused: %s)", nice, refused)
        if mode in ("topic", "both"):
            # Advertised before the network loads (which takes a while): a
            # SLAM node that sees a labels publisher holds its first frames
            # for the first labels (dynaorb_node ~first_labels_timeout)
            # instead of building its first map without them meanwhile.
            self.pub = rospy.Publisher("labels", Image, queue_size=2)
        self.segmenter = Segmenter(resolve_model(model), threads=threads)
        card = self.segmenter.card
        rospy.set_param("~labels", list(card.labels))
        rospy.set_param("~movable_ids", list(card.movable))
        self.bridge = CvBridge()
        self.net_lock = threading.Lock()   # one network, shared by the service and the topic worker
        self.cv = threading.Condition()
        self.pending = None  # the newest Image / CompressedImage not yet segmented
        self.dropped = self.published = self.failures = 0
        if mode in ("service", "both"):
            self.srv = rospy.Service("segment", Segment, self.on_segment)
        if mode in ("topic", "both"):
            if transport == "compressed":  # under the image topic as remapped, as image_transport names it
                self.sub = rospy.Subscriber(rospy.resolve_name("image") + "/compressed", CompressedImage,
                                            self.on_image, queue_size=1, buff_size=1 << 24)
            else:
                self.sub = rospy.Subscriber("image", Image, self.on_image, queue_size=1, buff_size=1 << 24)
            threading.Thread(target=self.worker, name="segmentation", daemon=True).start()
        rospy.loginfo("segmentation_server: %s (%s, %d threads, nice +%d), mode %s; movable: %s", card.name,
                      self.segmenter.path, threads, nice, mode, ", ".join(card.movable_names))

    def labels_msg(self, msg):
        """(label Image with msg's header, inference ms) for an Image or a
        CompressedImage; ValueError on an image it cannot read."""
        if isinstance(msg, CompressedImage):
            image = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"compressed image ('{msg.format}', {len(msg.data)} bytes) does not decode")
        else:
            try:
                image = self.bridge.imgmsg_to_cv2(msg, desired_encoding="bgr8")
            except CvBridgeError as exc:
                raise ValueError(f"cannot read a {msg.width}x{msg.height} '{msg.encoding}' image: {exc}") from None
        with self.net_lock:
            seg = self.segmenter.segment(image)
        out = self.bridge.cv2_to_imgmsg(seg.labels, encoding="mono8")
        out.header = msg.header
        return out, seg.inference_ms

    def on_segment(self, req):
        try:
            labels, ms = self.labels_msg(req.image)
        except ValueError as exc:
            raise rospy.ServiceException(f"segment: {exc}") from None
        card = self.segmenter.card
        return SegmentResponse(labels=labels, class_names=list(card.labels), movable_ids=list(card.movable),
                               inference_ms=ms)

    def on_image(self, msg: Image) -> None:
        with self.cv:
            if self.pending is not None:
                self.dropped += 1
            self.pending = msg
            self.cv.notify()

    def worker(self) -> None:
        while not rospy.is_shutdown():
            with self.cv:
                if not self.cv.wait_for(lambda: self.pending is not None, timeout=0.5):
                    continue
                msg, self.pending = self.pending, None
            try:
                labels, _ = self.labels_msg(msg)
            except Exception as exc:  # keep serving: log once per 10 s, count all
                self.failures += 1
                rospy.logwarn_throttle(10.0, f"segmentation_server: frame skipped ({exc}); "
                                             f"{self.failures} failures so far")
                continue
            self.pub.publish(labels)
            self.published += 1


def main() -> None:
    rospy.init_node("segmentation_server")
    try:
        SegmentationServer()
    except (ValueError, FileNotFoundError) as exc:
        rospy.logfatal("segmentation_server: %s", exc)
        raise SystemExit(1)
    rospy.spin()
