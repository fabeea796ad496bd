"""Reads a hetsim ROS 2 recording the way ROS 2 and Foxglove tooling do, independently of
hetsim's own code, and checks it against the run's metrics.json.

  check_mcap.py RUN.mcap RESULTS_DIR

- Foxglove's decoder (mcap-ros2-support) decodes every message from the ros2msg definitions
  stored in the file, as Foxglove Studio does.
- rosbags decodes every message again: the standard types with its own built-in ROS 2
  Humble definitions (so the bytes must match real sensor_msgs, geometry_msgs and tf2_msgs
  layouts, not only our definitions of them), hetsim_msgs with the definitions in the file.
- The two decodings agree on header stamps, and each topic holds exactly the number of
  messages the run delivered (metrics.json `messages`).
- Every channel offers its QoS as rosbag2 reads it (`/tf_static` transient local).

Prints one line per topic and `ros2-mcap: N passed, 0 failed`; exits 1 on any mismatch.
"""

import json
import sys
from collections import Counter
from pathlib import Path

from mcap.reader import make_reader
from ruamel.yaml import YAML
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def main() -> int:
    path, results = Path(sys.argv[1]), Path(sys.argv[2])
    store = get_typestore(Stores.ROS2_HUMBLE)
    failures = []
    counts = Counter()
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        if header.profile != "ros2":
            failures.append(f"profile {header.profile!r}, expected 'ros2'")
        summary = reader.get_summary()
        custom = {}
        for schema in summary.schemas.values():
            if schema.encoding != "ros2msg":
                failures.append(f"schema {schema.name}: encoding {schema.encoding}")
            if schema.name.startswith("hetsim_msgs/"):
                custom.update(get_types_from_msg(schema.data.decode(), schema.name))
            elif schema.name not in store.fielddefs:
                failures.append(f"{schema.name} is not a ROS 2 Humble type")
        store.register(custom)
        for channel in summary.channels.values():
            if channel.message_encoding != "cdr":
                failures.append(f"{channel.topic}: message encoding {channel.message_encoding}")
            # The profile's required channel metadata, as rosbag2 parses it.
            qos = YAML(typ="safe").load(channel.metadata.get("offered_qos_profiles", "") or "[]")
            latched = channel.topic == "/tf_static"
            if not (isinstance(qos, list) and qos and qos[0].get("durability") == (1 if latched else 2)):
                failures.append(f"{channel.topic}: offered_qos_profiles {qos!r}")
        for schema, channel, message, foxglove in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            ros = store.deserialize_cdr(message.data, schema.name)
            if hasattr(ros, "header"):
                a = (ros.header.stamp.sec, ros.header.stamp.nanosec, ros.header.frame_id)
                b = (foxglove.header.stamp.sec, foxglove.header.stamp.nanosec, foxglove.header.frame_id)
                if a != b:
                    failures.append(f"{channel.topic}: rosbags {a} vs foxglove {b}")
                if a[0] * 1_000_000_000 + a[1] != message.log_time:
                    failures.append(f"{channel.topic}: stamp {a} vs log time {message.log_time}")
            if schema.name == "sensor_msgs/msg/Image":
                channels = {"rgb8": 3, "mono8": 1}.get(ros.encoding)
                if channels is None or ros.step != channels * ros.width or len(ros.data) != ros.step * ros.height:
                    failures.append(f"{channel.topic}: image {ros.width}x{ros.height} {ros.encoding}, {len(ros.data)} bytes")
    delivered = json.loads((results / "metrics.json").read_text())["messages"]
    for topic, n in sorted(delivered.items()):
        if topic.endswith("/truth"):
            continue
        recorded = counts.get(f"/{topic}", 0)
        if recorded != n:
            failures.append(f"/{topic}: {recorded} recorded, {n} delivered")
    for topic, n in sorted(counts.items()):
        print(f"{topic}: {n} messages decoded by both")
    for f in failures:
        print(f"FAILED: {f}")
    checks = len(counts) + len(delivered)
    print(f"ros2-mcap: {checks - len(failures)} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
