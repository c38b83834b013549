"""Reads `formation-tracker track --mcap` outputs with the Python `mcap` reader and checks them.

For every file: the summary (channels, statistics) is read through the index, every message
is read, the CDR images are decoded by `mcap-ros2-support` from their ros2msg schema, and
every JSON message is checked against its channel's JSON schema (the subset of JSON Schema
the schemas use: object/properties, array/items/minItems/maxItems, number, integer, string,
enum). Run only from `cargo xtask bags`.
"""

import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def validate(value, schema, where):
    kind = schema.get("type")
    if "enum" in schema and value not in schema["enum"]:
        raise ValueError(f"{where}: {value!r} not in {schema['enum']}")
    if kind == "object":
        if not isinstance(value, dict):
            raise ValueError(f"{where}: not an object")
        props = schema.get("properties", {})
        for key, v in value.items():
            if key not in props:
                raise ValueError(f"{where}: field {key!r} is not in the schema")
            validate(v, props[key], f"{where}.{key}")
    elif kind == "array":
        if not isinstance(value, list):
            raise ValueError(f"{where}: not an array")
        if len(value) < schema.get("minItems", 0) or len(value) > schema.get("maxItems", 1 << 62):
            raise ValueError(f"{where}: {len(value)} items")
        for i, v in enumerate(value):
            validate(v, schema.get("items", {}), f"{where}[{i}]")
    elif kind == "number":
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise ValueError(f"{where}: not a number")
    elif kind == "integer":
        if not isinstance(value, int) or isinstance(value, bool):
            raise ValueError(f"{where}: not an integer")
    elif kind == "string":
        if not isinstance(value, str):
            raise ValueError(f"{where}: not a string")


def check(path):
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            raise ValueError(f"{path}: no summary")
        topics = {c.topic for c in summary.channels.values()}
        for needed in ["/camera/annotations", "/tf", "/formation/estimate"]:
            if needed not in topics:
                raise ValueError(f"{path}: no {needed} channel")
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if schema.encoding == "jsonschema":
                validate(json.loads(message.data), json.loads(schema.data), f"{channel.topic}#{counts[channel.topic] - 1}")
        f.seek(0)
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=["/camera/image"]):
            if decoded.encoding != "mono8" or len(decoded.data) != decoded.width * decoded.height:
                raise ValueError(f"{path}: image message is not a whole mono8 image")
        total = sum(counts.values())
        if total != summary.statistics.message_count:
            raise ValueError(f"{path}: read {total} messages, the statistics say {summary.statistics.message_count}")
    print(f"check_mcap: {path}: {counts} valid")


if __name__ == "__main__":
    for p in sys.argv[1:]:
        check(p)
