"""A ROS 2 bag writer for tests that is not Hearth's recorder: mcap-ros2-support's writer with
message definitions written out here by hand (as they are in ROS 2 Humble)."""
from __future__ import annotations

import math

import numpy as np
from mcap_ros2.writer import Writer

SEP = "=" * 80 + "\n"
HEADER = ("MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + SEP
          + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
IMAGE = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
         "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + SEP + HEADER)
CAMERA_INFO = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
               "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
               "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n" + SEP + HEADER + SEP
               + "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\n"
               "uint32 height\nuint32 width\nbool do_rectify\n")
TF = ("geometry_msgs/TransformStamped[] transforms\n" + SEP
      + "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
      "geometry_msgs/Transform transform\n" + SEP + HEADER + SEP
      + "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\n"
      "geometry_msgs/Quaternion rotation\n" + SEP
      + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n" + SEP
      + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n")


def header(ns: int, frame: str) -> dict:
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
            "frame_id": frame}


def quaternion(R) -> dict:
    from scipy.spatial.transform import Rotation
    x, y, z, w = Rotation.from_matrix(np.asarray(R)[:3, :3]).as_quat()
    return {"x": x, "y": y, "z": z, "w": w}


def transform(ns: int, parent: str, child: str, T) -> dict:
    T = np.asarray(T, dtype=float)
    return {"header": header(ns, parent), "child_frame_id": child,
            "transform": {"translation": {"x": T[0, 3], "y": T[1, 3], "z": T[2, 3]},
                          "rotation": quaternion(T)}}


class BagFile:
    """An .mcap file with ROS 2 messages: ``image``, ``camera_info``, ``tf``."""

    def __init__(self, path):
        self.f = open(path, "wb")
        self.w = Writer(self.f)
        self.schemas = {name: self.w.register_msgdef(name, text) for name, text in
                        (("sensor_msgs/msg/Image", IMAGE),
                         ("sensor_msgs/msg/CameraInfo", CAMERA_INFO),
                         ("tf2_msgs/msg/TFMessage", TF))}

    def image(self, topic: str, ns: int, frame: str, array: np.ndarray, encoding: str) -> None:
        a = np.ascontiguousarray(array)
        h, w = a.shape[:2]
        self.w.write_message(topic, self.schemas["sensor_msgs/msg/Image"], {
            "header": header(ns, frame), "height": h, "width": w, "encoding": encoding,
            "is_bigendian": 0, "step": a.nbytes // h, "data": a.tobytes()}, log_time=ns)

    def camera_info(self, topic: str, ns: int, frame: str, K, d=(0.0,) * 5) -> None:
        self.w.write_message(topic, self.schemas["sensor_msgs/msg/CameraInfo"], {
            "header": header(ns, frame), "height": K.height, "width": K.width,
            "distortion_model": "plumb_bob", "d": list(d),
            "k": [K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1], "r": [1, 0, 0, 0, 1, 0, 0, 0, 1],
            "p": [K.fx, 0, K.cx, 0, 0, K.fy, K.cy, 0, 0, 0, 1, 0], "binning_x": 0,
            "binning_y": 0, "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0,
                                    "do_rectify": False}}, log_time=ns)

    def tf(self, ns: int, transforms: list, static: bool = False) -> None:
        self.w.write_message("/tf_static" if static else "/tf", self.schemas["tf2_msgs/msg/TFMessage"],
                             {"transforms": transforms}, log_time=ns)

    def close(self) -> None:
        self.w.finish()
        self.f.close()


def planar(x: float, y: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    T[:2, 3] = x, y
    return T
