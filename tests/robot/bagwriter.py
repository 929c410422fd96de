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


class RealSenseBag:
    """A rosbag2 directory (MCAP storage) written with ``rosbags``' own writer and ROS 2
    Humble's message types, laid out as a RealSense D4xx driver records: colour as a JPEG
    ``CompressedImage`` with plumb-bob distortion, depth unregistered (16UC1 millimetres in
    the depth camera's own frame and intrinsics) with its own camera_info, tf."""

    def __init__(self, path):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.t = self.ts.types
        self.w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.w.open()
        self.conns: dict = {}

    def _write(self, topic: str, msgtype: str, msg, ns: int) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts)
        self.w.write(self.conns[topic], ns, self.ts.serialize_cdr(msg, msgtype))

    def _header(self, ns: int, frame: str):
        return self.t["std_msgs/msg/Header"](
            stamp=self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                        nanosec=ns % 1_000_000_000),
            frame_id=frame)

    def image(self, topic: str, ns: int, frame: str, array: np.ndarray, encoding: str) -> None:
        a = np.ascontiguousarray(array)
        h, w = a.shape[:2]
        self._write(topic, "sensor_msgs/msg/Image", self.t["sensor_msgs/msg/Image"](
            header=self._header(ns, frame), height=h, width=w, encoding=encoding,
            is_bigendian=0, step=a.nbytes // h,
            data=np.frombuffer(a.tobytes(), dtype=np.uint8)), ns)

    def jpeg(self, topic: str, ns: int, frame: str, rgb: np.ndarray, quality: int = 95) -> None:
        import cv2
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]),
                               [cv2.IMWRITE_JPEG_QUALITY, quality])
        assert ok
        self._write(topic, "sensor_msgs/msg/CompressedImage",
                    self.t["sensor_msgs/msg/CompressedImage"](
                        header=self._header(ns, frame), format="rgb8; jpeg compressed bgr8",
                        data=buf.ravel().astype(np.uint8)), ns)

    def camera_info(self, topic: str, ns: int, frame: str, K, d=(0.0,) * 5) -> None:
        f64 = np.float64
        self._write(topic, "sensor_msgs/msg/CameraInfo", self.t["sensor_msgs/msg/CameraInfo"](
            header=self._header(ns, frame), height=K.height, width=K.width,
            distortion_model="plumb_bob", d=np.asarray(d, f64),
            k=np.array([K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1], f64),
            r=np.eye(3).ravel(), p=np.array([K.fx, 0, K.cx, 0, 0, K.fy, K.cy, 0, 0, 0, 1, 0], f64),
            binning_x=0, binning_y=0, roi=self.t["sensor_msgs/msg/RegionOfInterest"](
                x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)), ns)

    def tf(self, ns: int, transforms: list, static: bool = False) -> None:
        msgs = []
        for tr in transforms:
            t, q = tr["transform"]["translation"], tr["transform"]["rotation"]
            stamp = tr["header"]["stamp"]
            msgs.append(self.t["geometry_msgs/msg/TransformStamped"](
                header=self._header(stamp["sec"] * 1_000_000_000 + stamp["nanosec"],
                                    tr["header"]["frame_id"]),
                child_frame_id=tr["child_frame_id"],
                transform=self.t["geometry_msgs/msg/Transform"](
                    translation=self.t["geometry_msgs/msg/Vector3"](x=t["x"], y=t["y"], z=t["z"]),
                    rotation=self.t["geometry_msgs/msg/Quaternion"](x=q["x"], y=q["y"], z=q["z"],
                                                                    w=q["w"]))))
        self._write("/tf_static" if static else "/tf", "tf2_msgs/msg/TFMessage",
                    self.t["tf2_msgs/msg/TFMessage"](transforms=msgs), ns)

    def close(self) -> None:
        self.w.close()


def distort(img: np.ndarray, K, D) -> np.ndarray:
    """What a camera with distortion ``D`` sees of the pinhole image ``img`` (intrinsics
    ``K``): each distorted pixel samples the pinhole image where it undistorts to."""
    import cv2
    w, h = K.width, K.height
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
    und = cv2.undistortPoints(pts, K.matrix(), np.asarray(D, float), P=K.matrix()).reshape(h, w, 2)
    return cv2.remap(img, und[..., 0], und[..., 1], cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)
