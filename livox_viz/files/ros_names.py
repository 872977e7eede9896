"""ROS 2 names a bag may use: topic names as rmw validates a fully qualified one, frame ids as tf2 does.

A bag holds fully qualified topic names (what ``ros2 bag record`` writes), so a
topic must start with ``/``; its tokens hold only ASCII letters, digits and
``_``, and none starts with a digit (``rmw_validate_full_topic_name``). A frame
id must not be empty nor start with ``/`` (tf2's ``validateFrameId``); we also
refuse whitespace, which tf2 accepts but every command-line tool splits. The
names of one bag must not collide: each topic carries one message type (and
``/tf``, ``/tf_static`` are the bag's own), and the frames of the transform
tree are distinct (tf2 ignores a transform from a frame to itself).
"""

from __future__ import annotations

import re

from livox_viz.core.errors import LivoxVizError

#: rmw's limit: 255 characters less 8 reserved for the middleware's prefixes.
MAX_TOPIC_LENGTH = 255 - 8
#: Topics every bag of ours writes itself, whatever the user names the others.
RESERVED_TOPICS = ("/tf", "/tf_static")
_TOPIC_CHARACTER = re.compile(r"[A-Za-z0-9_/]")


def topic_name_problem(name: str) -> str | None:
    """What is wrong with a fully qualified ROS 2 topic name, in rmw's words, or None if it is valid."""
    if not name:
        return "topic name must not be empty"
    if not name.startswith("/"):
        return "topic name must be absolute, it must lead with a '/'"
    if name.endswith("/"):
        return "topic name must not end with a '/'"
    bad = next((c for c in name if not _TOPIC_CHARACTER.fullmatch(c)), None)
    if bad is not None:
        return f"topic name must not contain {bad!r}: only letters, digits, '_' and '/'"
    if "//" in name:
        return "topic name must not contain repeated '/'"
    if re.search(r"/[0-9]", name):
        return "topic name tokens must not start with a number"
    if len(name) > MAX_TOPIC_LENGTH:
        return f"topic name must not be longer than {MAX_TOPIC_LENGTH} characters"
    return None


def frame_id_problem(name: str) -> str | None:
    """What is wrong with a tf2 frame id, or None if it is valid."""
    if not name:
        return "frame id must not be empty"
    if name.startswith("/"):
        return "tf2 frame ids cannot start with a '/'"
    if any(c.isspace() or not c.isprintable() for c in name):
        return "frame id must not contain spaces or control characters"
    return None


def check_ros_names(topics: dict[str, str], frames: dict[str, str], tree: tuple[str, ...]) -> None:
    """Refuse invalid or colliding names in one line.

    Parameters
    ----------
    topics : dict of str to str
        Role (``lidar``, ``imu``, ...) to topic name; every topic has its own message type.
    frames : dict of str to str
        Role (``lidar_frame``, ...) to frame id.
    tree : tuple of str
        The roles whose frames form the transform tree (they must all differ).

    Raises
    ------
    LivoxVizError
        Naming the role, the value and the rule it breaks.
    """
    for role, name in topics.items():
        problem = topic_name_problem(name)
        if problem is not None:
            raise LivoxVizError(f"ROS name {role}={name}: {problem}")
        if name in RESERVED_TOPICS:
            raise LivoxVizError(f"ROS name {role}={name}: {name} is the bag's own transform topic "
                                "(tf2_msgs/msg/TFMessage); allowed: another topic")
    for role, name in frames.items():
        problem = frame_id_problem(name)
        if problem is not None:
            raise LivoxVizError(f"ROS name {role}={name}: {problem}")
    for kind, names in (("topic", topics), ("frame", {role: frames[role] for role in tree})):
        seen: dict[str, str] = {}
        for role, name in names.items():
            if name in seen:
                reason = "one topic carries one message type" if kind == "topic" else \
                    "the transform tree needs distinct frames"
                raise LivoxVizError(f"ROS names {seen[name]}={name} and {role}={name} collide: {reason}; "
                                    f"allowed: a different {kind} for each")
            seen[name] = role
