#!/usr/bin/python3
"""Black-box check of a fabrikd binary against the wire contract (v1).

Written from ../shared/wire-contract.md and proto/ only: it starts the daemon
with a temporary config on free loopback ports, talks to it through pyzmq, and
validates every pose, stats and model payload against proto/*.schema.json.

    /usr/bin/python3 tests/contract/contract_client.py --fabrikd build/src/apps/fabrikd

Exit code 0 when every check passes, 1 with a message naming the first failed
check otherwise (and the tail of the daemon's log).
"""
import argparse
import json
import math
import os
import pathlib
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time

import jsonschema
import msgpack
import zmq

ROOT = pathlib.Path(__file__).resolve().parents[2]
MAX_PAYLOAD = 64 * 1024  # input.max_payload_bytes of the test config
STATS_INTERVAL_S = 0.2
ANSWER_TIMEOUT_S = 3.0  # a frame that is not answered by then is lost
WINDOW = 8  # frames in flight in the streaming check, well under the input queue
PROBE_BASE = 9_000_000  # frame numbers of slow-joiner probes
BAD_BASE = 8_000_000  # frame numbers inside bad payloads: must never be answered


class CheckFailed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise CheckFailed(message)


# ---------------------------------------------------------------- the model


def rest_positions(model_path):
    """Rest world positions (mm) of the model's markers and joints.

    A segment's base sits at root_position (root) or at the parent's point of
    that name; every frame is parallel to the world frame at rest."""
    model = json.loads(model_path.read_text())
    scale = {"mm": 1.0, "m": 1000.0}[model["units"]]
    base_world = {}
    points_world = {}
    markers, joints = {}, {}
    for seg in model["segments"]:  # parents precede children in the file
        if "parent" not in seg:
            base = [c * scale for c in model.get("root_position", [0, 0, 0])]
        else:
            base = points_world[seg["base"]]
        base_world[seg["name"]] = base
        joints[seg["base"]] = base
        for name, p in seg.get("points", {}).items():
            points_world[name] = [b + c * scale for b, c in zip(base, p)]
        for name, p in seg.get("markers", {}).items():
            markers[name] = [b + c * scale for b, c in zip(base, p)]
    root = [c * scale for c in model.get("root_position", [0, 0, 0])]
    return markers, joints, root


def moved(points, root, t):
    """`points` turned about the vertical through `root` and walked along X:
    an exact rigid motion the model can follow."""
    theta = 0.4 * math.sin(2 * math.pi * 0.5 * t)
    c, s = math.cos(theta), math.sin(theta)
    dx = 300.0 * math.sin(2 * math.pi * 0.25 * t)
    out = {}
    for name, (x, y, z) in points.items():
        rx, rz = x - root[0], z - root[2]
        out[name] = [root[0] + c * rx + s * rz + dx, y, root[2] - s * rx + c * rz]
    return out


# ---------------------------------------------------------------- plumbing


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def decode(payload):
    """JSON or MessagePack, told apart by the first byte (as the contract says)."""
    check(len(payload) > 0, "empty payload from the daemon")
    first = payload[0]
    if first in b"{ \t\r\n":
        return json.loads(payload.decode("utf-8")), "json"
    check(0x80 <= first <= 0x8F or first in (0xDE, 0xDF),
          f"output payload starts with byte 0x{first:02x}: neither JSON nor a MessagePack map")
    return msgpack.unpackb(payload, raw=False, strict_map_key=False), "msgpack"


def load_schema(name):
    schema = json.loads((ROOT / "proto" / name).read_text())
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


class Daemon:
    """One fabrikd process with its config, log and sockets."""

    def __init__(self, fabrikd, workdir, output_encoding="json", output_units="mm",
                 measured_markers=False, pose_content=None, subjects=None, views=None):
        self.in_ep = f"tcp://127.0.0.1:{free_port()}"
        self.out_ep = f"tcp://127.0.0.1:{free_port()}"
        self.output_units = output_units
        self.output_encoding = output_encoding
        config = {
            "format": "fabrikd-config/1",
            "description": "contract_client.py: config/default.json on free ports",
            "model": "models/fullbody.json",  # not on disk next to this file: the embedded one
            "targets": {"default": {"level": 0, "weight": 1.0},
                        "markers": {m: {"level": 1} for m in ("RASI", "LASI", "RPSI", "LPSI")}},
            "solver": {"tolerance_mm": 0.1, "stall_tolerance_mm": 0.1, "max_iterations": 50,
                       "segment_fit": "rigid", "root": "free", "priorities": True},
            "input": {"endpoint": self.in_ep, "mode": "bind", "units": "mm",
                      "max_payload_bytes": MAX_PAYLOAD,
                      # every frame of a burst must be answered, none dropped as stale
                      "max_backlog_frames": 10000},
            "output": {"endpoint": self.out_ep, "mode": "bind", "encoding": output_encoding,
                       "units": output_units, "measured_markers": measured_markers},
            "stats_interval_s": STATS_INTERVAL_S,
            "log_level": "info",
        }
        if pose_content is not None:
            config["output"]["pose_content"] = pose_content
        if views is not None:
            config["output"]["views"] = views
        if subjects:
            # Several subjects (docs/multi-subject.md): the tracking parts of
            # the config above become each subject's own config file.
            one = {k: config.pop(k) for k in ("model", "targets", "solver")}
            one["format"] = "fabrikd-config/1"
            load_schema("daemon-config.schema.json").validate(one)
            for name in subjects:
                (pathlib.Path(workdir) / f"subject-{name}.json").write_text(json.dumps(one))
            config["subjects"] = [{"name": n, "config": f"subject-{n}.json"} for n in subjects]
        load_schema("daemon-config.schema.json").validate(config)
        tag = f"{output_encoding}-{output_units}" + ("" if pose_content is None else "-content") + \
            ("-subjects" if subjects else "") + ("-views" if views else "")
        self.config_path = pathlib.Path(workdir) / f"fabrikd-{tag}.json"
        self.config_path.write_text(json.dumps(config, indent=2))
        self.log_path = pathlib.Path(workdir) / f"fabrikd-{tag}.log"
        self.log = open(self.log_path, "wb")
        self.proc = subprocess.Popen([fabrikd, "--config", str(self.config_path)],
                                     stdout=self.log, stderr=subprocess.STDOUT, cwd=workdir)
        self.ctx = zmq.Context()
        self.pub = self.ctx.socket(zmq.PUB)
        self.pub.setsockopt(zmq.LINGER, 0)
        self.pub.setsockopt(zmq.SNDHWM, 100000)
        self.pub.connect(self.in_ep)
        self.sub = self.ctx.socket(zmq.SUB)
        self.sub.setsockopt(zmq.LINGER, 0)
        self.sub.setsockopt(zmq.RCVHWM, 100000)
        self.sub.setsockopt(zmq.SUBSCRIBE, b"pose")
        self.sub.setsockopt(zmq.SUBSCRIBE, b"stats")
        self.sub.setsockopt(zmq.SUBSCRIBE, b"model")
        self.sub.connect(self.out_ep)
        self.pose_schema = load_schema("pose.schema.json")
        self.stats_schema = load_schema("stats.schema.json")
        self.model_schema = load_schema("model.schema.json")
        self.models = []  # every model message
        self.poses = {}  # frame -> list of poses
        self.subjects = subjects or []
        self.subject_poses = {}  # (subject, frame) -> pose, from topics pose/SUBJECT
        self.stats = []  # (arrival time, stats)
        self.encodings = set()

    def send(self, payload, topic=b"markers"):
        self.pub.send_multipart([topic, payload])

    def check_running(self):
        rc = self.proc.poll()
        check(rc is None, f"fabrikd exited on its own with code {rc}")

    def pump(self, timeout_s):
        """Receives for up to timeout_s (returns early on the first message);
        validates and records every pose, stats and model."""
        if not self.sub.poll(int(timeout_s * 1000)):
            self.check_running()
            return False
        while True:
            parts = self.sub.recv_multipart()
            check(len(parts) == 2, f"output message with {len(parts)} frames, expected 2")
            topic, payload = parts
            doc, enc = decode(payload)
            self.encodings.add(enc)
            check(enc == self.output_encoding,
                  f"output encoding {enc}, config says {self.output_encoding}")
            subject_topic = topic.split(b"/", 1)
            if len(subject_topic) == 2 and subject_topic[1].decode() in self.subjects:
                check(subject_topic[0] in (b"pose", b"model"), f"unexpected output topic {topic!r}")
                topic, name = subject_topic[0], subject_topic[1].decode()
                if topic == b"pose":
                    check(doc.get("subject") == name,
                          f"pose on pose/{name} carries subject {doc.get('subject')!r}")
                    self.subject_poses[(name, doc["frame"])] = doc
            elif self.subjects:
                check(topic == b"stats", f"topic {topic!r} from a daemon of several subjects")
            if topic == b"pose":
                errors = list(self.pose_schema.iter_errors(doc))
                check(not errors, f"pose violates proto/pose.schema.json: {errors[:1]}")
                self.poses.setdefault(doc["frame"], []).append(doc)
            elif topic == b"stats":
                errors = list(self.stats_schema.iter_errors(doc))
                check(not errors, f"stats violates proto/stats.schema.json: {errors[:1]}")
                self.stats.append((time.monotonic(), doc))
            elif topic == b"model":
                errors = list(self.model_schema.iter_errors(doc))
                check(not errors, f"model violates proto/model.schema.json: {errors[:1]}")
                self.models.append(doc)
            else:
                raise CheckFailed(f"unexpected output topic {topic!r}")
            if not self.sub.poll(0):
                return True

    def wait_for(self, predicate, timeout_s, what):
        deadline = time.monotonic() + timeout_s
        while not predicate():
            left = deadline - time.monotonic()
            check(left > 0, f"timed out after {timeout_s:.1f} s waiting for {what}")
            self.pump(left)

    def wait_pose(self, frame, what=None):
        self.wait_for(lambda: frame in self.poses, ANSWER_TIMEOUT_S,
                      what or f"the pose of frame {frame}")
        return self.poses[frame][-1]

    def stats_after(self, t):
        """The first stats message that arrived after monotonic time t."""
        self.wait_for(lambda: any(a > t for a, _ in self.stats), 3 * max(STATS_INTERVAL_S, 1.0),
                      "a stats message")
        return next(s for a, s in self.stats if a > t)

    def join(self):
        """Slow joiner: publish probe frames until the first pose comes back,
        so that both subscriptions are known to have propagated."""
        deadline = time.monotonic() + 15.0
        frame = PROBE_BASE
        while not self.poses:
            self.check_running()
            check(time.monotonic() < deadline,
                  "no pose within 15 s of starting fabrikd (probe frames unanswered)")
            self.send(json.dumps({"frame": frame, "markers": {}}).encode())
            frame += 1
            self.pump(0.05)

    def stop(self):
        """SIGTERM; the daemon must exit with code 0 within 1 s."""
        self.check_running()
        self.proc.send_signal(signal.SIGTERM)
        try:
            rc = self.proc.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise CheckFailed("fabrikd did not exit within 1 s of SIGTERM")
        check(rc == 0, f"fabrikd exited with code {rc} after SIGTERM, expected 0")

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        # On any failure, show what the daemon logged before it is torn down.
        if exc_type is not None:
            print(f"--- tail of {self.log_path} ---\n{self.log_tail()}", file=sys.stderr)
        self.close()
        return False

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.sub.close()
        self.pub.close()
        self.ctx.term()
        self.log.close()

    def log_tail(self, lines=30):
        try:
            return "\n".join(self.log_path.read_text(errors="replace").splitlines()[-lines:])
        except OSError:
            return "(no log)"


# ---------------------------------------------------------------- checks


def dist(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


def check_pose(pose, sent, frame, time_s, rest_joints_moved, model_markers, joint_names,
               units="mm", expect_occluded=()):
    """A pose answers one marker frame: same frame and time, every joint and
    model marker, occluded markers listed with finite positions, residual
    consistent with the positions it reports."""
    scale = {"mm": 1.0, "m": 1e-3}[units]
    where = f"pose of frame {frame}"
    check(pose["frame"] == frame, f"{where}: frame {pose['frame']}")
    if time_s is not None:
        got = pose.get("time")
        check(isinstance(got, (int, float)) and abs(got - time_s) <= 1e-9 * max(1.0, abs(time_s)),
              f"{where}: time {got}, sent {time_s}")
    check(pose["units"] == units, f"{where}: units {pose['units']}, expected {units}")
    check(set(pose["joints"]) == joint_names,
          f"{where}: joints {sorted(pose['joints'])}, model has {sorted(joint_names)}")
    check(set(pose["markers"]) == model_markers,
          f"{where}: markers differ from the model's: "
          f"missing {sorted(model_markers - set(pose['markers']))}, "
          f"extra {sorted(set(pose['markers']) - model_markers)}")
    for group in ("joints", "markers"):
        for name, p in pose[group].items():
            check(all(math.isfinite(c) for c in p), f"{where}: {group}.{name} = {p} not finite")
    occluded = set(pose["occluded"])
    check(occluded == set(expect_occluded),
          f"{where}: occluded {sorted(occluded)}, expected {sorted(expect_occluded)}")
    visible = [m for m in model_markers if m not in occluded]
    res = pose["residual"]
    check(res["count"] == len(visible),
          f"{where}: residual.count {res['count']}, {len(visible)} markers visible")
    if visible:
        d = {m: dist(pose["markers"][m], [c * scale for c in sent[m]]) for m in visible}
        rms = math.sqrt(sum(v * v for v in d.values()) / len(d))
        worst = max(d, key=d.get)
        tol = 1e-3 * max(1.0, rms)
        check(abs(res["rms"] - rms) <= tol + 1e-4 * scale,
              f"{where}: residual.rms {res['rms']} but the reported markers give {rms}")
        check(abs(res["max"] - d[worst]) <= tol + 1e-4 * scale,
              f"{where}: residual.max {res['max']} but the reported markers give {d[worst]}")
        check(res["worst"] == worst or abs(d.get(res["worst"], -1) - d[worst]) <= tol,
              f"{where}: residual.worst {res['worst']} but the largest residual is {worst}")
        # The input is an exact rigid motion of the rest posture: the fit must be close.
        check(rms <= 2.0 * scale, f"{where}: residual rms {rms / scale:.3f} mm on exact data")
        for j, p in rest_joints_moved.items():
            e = dist(pose["joints"][j], [c * scale for c in p]) / scale
            check(e <= 10.0, f"{where}: joint {j} is {e:.1f} mm from the truth")
    else:
        check(res["worst"] is None, f"{where}: residual.worst {res['worst']} with count 0")


def check_model(model, pose, units):
    """The model message names exactly what the poses name, each once; its
    bones and segments refer to joints and segments it lists."""
    def names(entries):
        out = [e if isinstance(e, str) else e["name"] for e in entries]
        check(len(out) == len(set(out)), f"model: a name listed twice in {out}")
        return set(out)
    check(model["units"] == units, f"model: units {model['units']}, expected {units}")
    for key, pose_key in (("joints", "joints"), ("segments", "segments"), ("markers", "markers"),
                          ("coordinates", "angles")):
        check(names(model[key]) == set(pose[pose_key]),
              f"model.{key} differs from pose.{pose_key}: "
              f"{sorted(names(model[key]) ^ set(pose[pose_key]))}")
    joints, segments = set(model["joints"]), names(model["segments"])
    for a, b in model["bones"]:
        check(a in joints and b in joints and a != b, f"model: bone {a}-{b} is not two joints")
    check(len(model["bones"]) == len(segments) - 1, "model: not one bone per non-root segment")
    for s in model["segments"]:
        check(s["parent"] is None or s["parent"] in segments, f"model: segment {s}")
        check(s["origin"] in joints, f"model: segment {s} has no joint as origin")
    for m in model["markers"]:
        check(m["segment"] in segments, f"model: marker {m} on no segment of the model")
    for c in model["coordinates"]:
        lo, hi = c["min_deg"], c["max_deg"]
        check((lo is None) == (hi is None) and (lo is None or lo <= hi), f"model: coordinate {c}")


def stats_values(d):
    return {k: d[k] for k in ("frames_in", "frames_out", "decode_errors", "unknown_markers")}


def marker_frame(frame, markers, t=None, units=None):
    doc = {"frame": frame}
    if t is not None:
        doc["time"] = t
    if units is not None:
        doc["units"] = units
    doc["markers"] = markers
    return doc


def bad_payloads(valid_markers):
    """(name, list of frames of one ZeroMQ message) the daemon must drop and
    count in decode_errors. Frame numbers in them are BAD_BASE + i, so an
    answer to any of them is detected."""
    rng = random.Random(7)
    f = BAD_BASE
    mk = {"RASI": valid_markers["RASI"]}
    nested = b'{"frame": %d, "markers": {"RASI": ' % (f + 10) + b"[" * 20000 + b"]" * 20000 + b"}}"
    huge = json.dumps({"frame": f + 11, "markers": mk, "pad": "x" * (MAX_PAYLOAD + 1)}).encode()
    random_bytes = bytes([0xC1]) + bytes(rng.randrange(256) for _ in range(200))
    return [
        ("invalid JSON", [b"markers", b'{"frame": %d, "markers": {' % f]),
        ("frame is a string", [b"markers", json.dumps({"frame": str(f + 1), "markers": mk}).encode()]),
        ("frame is negative", [b"markers", json.dumps({"frame": -5, "markers": mk}).encode()]),
        ("frame is a fraction", [b"markers", json.dumps({"frame": f + 2.5, "markers": mk}).encode()]),
        ("markers is an array", [b"markers", json.dumps({"frame": f + 3, "markers": [1, 2]}).encode()]),
        ("a marker is a string",
         [b"markers", json.dumps({"frame": f + 4, "markers": {"RASI": "here"}}).encode()]),
        ("a marker has two coordinates",
         [b"markers", json.dumps({"frame": f + 5, "markers": {"RASI": [1.0, 2.0]}}).encode()]),
        ("top level is an array", [b"markers", json.dumps([f + 6, mk]).encode()]),
        ("missing frame", [b"markers", json.dumps({"markers": mk}).encode()]),
        ("NaN literal (not JSON)",
         [b"markers", b'{"frame": %d, "markers": {"RASI": [NaN, 1, 2]}}' % (f + 7)]),
        ("huge payload", [b"markers", huge]),
        ("deeply nested", [b"markers", nested]),
        ("random bytes", [b"markers", random_bytes]),
        ("empty payload", [b"markers", b""]),
        ("truncated MessagePack", [b"markers", msgpack.packb({"frame": f + 12, "markers": mk})[:-5]]),
        ("MessagePack frame is a string",
         [b"markers", msgpack.packb({"frame": str(f + 13), "markers": mk})]),
        ("MessagePack frame is NaN", [b"markers", msgpack.packb({"frame": float("nan"), "markers": mk})]),
        ("MessagePack without frame", [b"markers", msgpack.packb({"markers": mk})]),
        ("one-frame message", [b"markers"]),
        ("three-frame message",
         [b"markers", json.dumps({"frame": f + 14, "markers": mk}).encode(), b"extra"]),
    ]


def run_main(args, workdir, model_markers_rest, rest_joints, root):
    model_markers = set(model_markers_rest)
    joint_names = set(rest_joints)
    with Daemon(args.fabrikd, workdir) as d:
        d.join()
        print(f"contract: joined after {min(d.poses) - PROBE_BASE + 1} probe frame(s)")
        d.wait_for(lambda: d.models, ANSWER_TIMEOUT_S, "the model message after subscribing")
        check_model(d.models[0], d.poses[min(d.poses)][0], "mm")
        check("measured" not in d.poses[min(d.poses)][0],
              "pose carries measured while output.measured_markers is off")
        print("contract: the model message on subscribing names exactly the poses' joints, "
              "segments, markers and angles")

        # 1. N frames, alternating JSON and MessagePack, some in metres, some without units.
        frames = {}
        n = args.frames
        for i in range(n):
            frame = 1 + i
            t = round(i / 100.0, 6)
            markers = moved(model_markers_rest, root, t)
            units = [None, "mm", "m"][i % 3]
            scale = 1e-3 if units == "m" else 1.0
            payload_markers = {k: [c * scale for c in v] for k, v in markers.items()}
            doc = marker_frame(frame, payload_markers, t, units)
            # At most WINDOW frames unanswered: a burst beyond the input's
            # queue (ZeroMQ's high-water mark, a few dozen messages of this
            # config's size) is dropped by PUB/SUB by design, which a loaded
            # machine would turn into a lost frame here.
            if frame > WINDOW:
                d.wait_pose(frame - WINDOW)
            d.send(msgpack.packb(doc) if i % 2 else json.dumps(doc).encode())
            frames[frame] = (t, markers)
            d.pump(0)
        d.wait_for(lambda: all(f in d.poses for f in frames), ANSWER_TIMEOUT_S,
                   f"poses of all {n} frames "
                   f"(missing: {sorted(set(frames) - set(d.poses))[:10]}...)")
        for frame, (t, markers) in frames.items():
            check(len(d.poses[frame]) == 1, f"frame {frame} answered {len(d.poses[frame])} times")
            check_pose(d.poses[frame][0], markers, frame, t, moved(rest_joints, root, t),
                       model_markers, joint_names)
        print(f"contract: {n} frames (JSON, MessagePack; units mm, m, default) answered exactly "
              f"once, every pose valid")

        # 2. Occlusion: null, absent, NaN (MessagePack), and everything occluded.
        names = sorted(model_markers)
        cases = [
            ("null", names[0:3], lambda m, o: m.update({k: None for k in o}), "json"),
            ("absent", names[3:6], lambda m, o: [m.pop(k) for k in o], "json"),
            ("NaN in MessagePack", names[6:9],
             lambda m, o: m.update({k: [float("nan"), 1.0, 2.0] for k in o}), "msgpack"),
            ("infinity in MessagePack", names[9:10],
             lambda m, o: m.update({k: [1.0, float("inf"), 2.0] for k in o}), "msgpack"),
            ("mixed", names[0:1] + names[10:12],
             lambda m, o: (m.update({o[0]: None}), m.pop(o[1]),
                           m.update({o[2]: [0.0, 0.0, float("nan")]})), "msgpack"),
        ]
        frame = 1000
        for what, occ, apply, enc in cases:
            frame += 1
            t = 0.5
            markers = moved(model_markers_rest, root, t)
            sent = dict(markers)
            apply(sent, occ)
            doc = marker_frame(frame, sent, t)
            d.send(msgpack.packb(doc) if enc == "msgpack" else json.dumps(doc).encode())
            pose = d.wait_pose(frame)
            check_pose(pose, markers, frame, t, moved(rest_joints, root, t), model_markers,
                       joint_names, expect_occluded=occ)
        frame += 1
        d.send(json.dumps(marker_frame(frame, {k: None for k in names})).encode())
        pose = d.wait_pose(frame)
        check(pose["occluded"] and set(pose["occluded"]) == model_markers,
              "all-occluded frame: not every marker listed in occluded")
        check(pose["residual"]["count"] == 0 and pose["residual"]["worst"] is None,
              f"all-occluded frame: residual {pose['residual']}")
        check(pose["solver"]["status"] == "no_targets",
              f"all-occluded frame: solver.status {pose['solver']['status']}, expected no_targets")
        for name, p in pose["markers"].items():
            check(all(math.isfinite(c) for c in p), f"all-occluded frame: {name} = {p}")
        print("contract: occluded markers (null, absent, NaN, inf, all) listed, gap-filled, "
              "finite")

        # 3. Unknown markers are ignored and counted; a frame number going back is accepted.
        before = d.stats[-1][1] if d.stats else None
        frame += 1
        markers = moved(model_markers_rest, root, 0.25)
        d.send(json.dumps(marker_frame(frame, {**markers, "NOT_A_MARKER": [1, 2, 3]}, 0.25)).encode())
        check_pose(d.wait_pose(frame), markers, frame, 0.25, moved(rest_joints, root, 0.25),
                   model_markers, joint_names)
        d.send(json.dumps(marker_frame(7, markers, 0.25)).encode())
        d.wait_for(lambda: len(d.poses.get(7, [])) == 2, ANSWER_TIMEOUT_S,
                   "the answer to frame 7 sent again (frame numbers going back are accepted)")
        t_sent = time.monotonic()
        after = d.stats_after(t_sent)
        if before is not None:
            check(after["unknown_markers"] > before["unknown_markers"],
                  f"unknown_markers did not grow: {before['unknown_markers']} -> "
                  f"{after['unknown_markers']}")
        else:
            check(after["unknown_markers"] >= 1, "unknown_markers not counted")
        print("contract: unknown marker ignored and counted; backwards frame number accepted")

        # 4. Bad payloads, each followed by a valid frame that must be answered.
        base = d.stats_after(time.monotonic())
        battery = bad_payloads(markers)
        for what, parts in battery:
            d.pub.send_multipart(parts)
            frame += 1
            d.send(json.dumps(marker_frame(frame, markers, 0.25)).encode())
            d.wait_pose(frame, f"the valid frame after the bad payload '{what}' to be answered")
        answered_bad = [f for f in d.poses if BAD_BASE <= f < PROBE_BASE]
        check(not answered_bad, f"bad payloads were answered with poses: frames {answered_bad}")
        final = d.stats_after(time.monotonic())
        grew = final["decode_errors"] - base["decode_errors"]
        check(grew == len(battery),
              f"decode_errors grew by {grew} over {len(battery)} bad payloads "
              f"({base['decode_errors']} -> {final['decode_errors']})")
        print(f"contract: {len(battery)} bad payloads dropped and counted in decode_errors, "
              "daemon still answering")

        # 5. Hostile input: bytes that are not UTF-8, absurd numbers, zeros, a
        # message far over the limit. Each is survived, counted, and every pose
        # and stats after it is valid (pump() decodes and validates them all).
        run_hostile(d, markers, frame)

        # 6. Stats: at least once per second, counters never go back.
        arrivals = [a for a, _ in d.stats]
        gaps = [b - a for a, b in zip(arrivals, arrivals[1:])]
        check(gaps and max(gaps) <= 1.0 + 0.25,
              f"stats gap of {max(gaps):.2f} s (contract: at least once per second)")
        for (_, a), (_, b) in zip(d.stats, d.stats[1:]):
            for k, v in stats_values(a).items():
                check(b[k] >= v, f"stats counter {k} went back: {v} -> {b[k]}")
            check(b["uptime_s"] >= a["uptime_s"], "stats uptime_s went back")
        last = d.stats[-1][1]
        check(last["frames_out"] >= sum(len(v) for k, v in d.poses.items()) - 0,
              f"frames_out {last['frames_out']} below the poses received")
        print(f"contract: {len(d.stats)} stats messages valid, max gap {max(gaps):.2f} s; "
              f"last: {json.dumps(last, sort_keys=True)}")

        # 7. SIGTERM: exit code 0 within 1 s.
        d.stop()
        print("contract: SIGTERM -> exit code 0 within 1 s")


def run_hostile(d, markers, frame):
    """Section 5 of run_main."""
    base = d.stats_after(time.monotonic())
    frame = 5_000_000

    def answered(doc, what, raw=None, topic=b"markers"):
        """Sends doc (or raw bytes), then a valid frame that must be answered."""
        nonlocal frame
        d.send(raw if raw is not None else json.dumps(doc).encode(), topic)
        frame += 1
        d.send(json.dumps(marker_frame(frame, markers)).encode())
        d.wait_pose(frame, f"the valid frame after {what}")

    def raw_msgpack(f, name, value):
        """{"frame": f, "markers": {name: value}} with a name that need not be UTF-8."""
        return (b"\x82\xa5frame" + msgpack.packb(f) + b"\xa7markers\x81\xdb"
                + len(name).to_bytes(4, "big") + name + msgpack.packb(value))

    answered(marker_frame(1, markers), "a topic that is not UTF-8", topic=b"markers\xff")
    answered(None, "an unknown marker name that is not UTF-8",
             raw=raw_msgpack(frame + 100, b"\xff\xfe\x1b[31m", [1.0, 2.0, 3.0]))
    answered(None, "a bad marker whose name is not UTF-8",
             raw=raw_msgpack(BAD_BASE + 20, b"R\xc0\xaf\x00", "here"))
    answered(None, "a units string with control characters",
             raw=b'{"frame": %d, "units": "m\\u0000\\u001bm"}' % (BAD_BASE + 21))
    after_bytes = d.stats_after(time.monotonic())
    last_error = after_bytes["last_error"]
    check(isinstance(last_error, str) and "\\x1b" in last_error and len(last_error) <= 256,
          f"last_error not escaped: {last_error!r}")

    # Absurd but finite numbers: RASI occluded beyond 100 m, poses all numbers.
    cases = [("1e160", [1e160, 950.0, 120.0], True), ("1e308", [1e308, -1e308, 1e308], True),
             ("-0.0", [-0.0, 950.0, -0.0], False), ("subnormal", [5e-324, 950.0, -5e-324], False),
             ("zero", [0.0, 0.0, 0.0], True)]
    for i, (what, xyz, occluded) in enumerate(cases):
        for enc in ("json", "msgpack"):
            frame += 1
            doc = marker_frame(frame, {**markers, "RASI": xyz}, 0.25)
            d.send(msgpack.packb(doc) if enc == "msgpack" else json.dumps(doc).encode())
            pose = d.wait_pose(frame, f"the frame with RASI at {what} ({enc})")
            check(("RASI" in pose["occluded"]) == occluded,
                  f"RASI at {what} ({enc}): occluded {pose['occluded']}")
            check(all(math.isfinite(v) for v in (pose["residual"]["rms"], pose["residual"]["max"])),
                  f"RASI at {what} ({enc}): residual {pose['residual']}")
    for enc in ("json", "msgpack"):
        doc = marker_frame(2**64 - 1, markers, 1e308)
        d.send(msgpack.packb(doc) if enc == "msgpack" else json.dumps(doc).encode())
        pose = d.wait_pose(2**64 - 1, f"frame 2^64-1 ({enc})")
        check(pose["time"] == 1e308, f"frame 2^64-1: time {pose.get('time')}")
        d.poses.pop(2**64 - 1)
    after_numbers = d.stats_after(time.monotonic())
    check(after_numbers["rejected_coordinates"] - base["rejected_coordinates"] == 4,
          f"rejected_coordinates grew by "
          f"{after_numbers['rejected_coordinates'] - base['rejected_coordinates']}, expected 4")
    check(after_numbers["zero_markers"] - base["zero_markers"] == 2,
          f"zero_markers grew by {after_numbers['zero_markers'] - base['zero_markers']}, "
          "expected 2")

    # Far over the limit: refused by ZeroMQ, the connection dropped; this PUB
    # reconnects by itself and frames sent after it are answered again.
    d.pub.send_multipart([b"markers", b" " * (4 * MAX_PAYLOAD)])
    d.wait_for(lambda: d.stats and d.stats[-1][1]["input_disconnects"] > base["input_disconnects"],
               3.0, "input_disconnects to count the oversized message")
    frame += 1
    d.send(json.dumps(marker_frame(frame, markers)).encode())
    d.wait_pose(frame, "the valid frame after a message 4 times the payload limit")
    final = d.stats_after(time.monotonic())
    check(final["internal_errors"] == 0, f"internal_errors {final['internal_errors']}")
    answered_bad = [f for f in d.poses if BAD_BASE <= f < PROBE_BASE]
    check(not answered_bad, f"bad payloads were answered with poses: frames {answered_bad}")
    print("contract: hostile input (not UTF-8, 1e308, -0.0, subnormals, zeros, frame 2^64-1, "
          "a message 4x the limit) survived and counted; every pose and stats valid")


def run_msgpack_metres(args, workdir, model_markers_rest, rest_joints, root):
    """Output encoding msgpack and units m: poses come as MessagePack in metres."""
    with Daemon(args.fabrikd, workdir, output_encoding="msgpack", output_units="m",
                measured_markers=True) as d:
        d.join()
        hidden = sorted(model_markers_rest)[:3]
        for i in range(20):
            frame = 100 + i
            t = i / 100.0
            markers = moved(model_markers_rest, root, t)
            sent = {k: (None if k in hidden and i % 2 else v) for k, v in markers.items()}
            d.send(json.dumps(marker_frame(frame, sent, t, "mm")).encode())
            pose = d.wait_pose(frame)
            check_pose(pose, markers, frame, t, moved(rest_joints, root, t),
                       set(model_markers_rest), set(rest_joints), units="m",
                       expect_occluded=[k for k, v in sent.items() if v is None])
            # output.measured_markers: the visible markers as sent, in metres.
            measured = pose.get("measured")
            check(measured is not None, f"pose of frame {frame}: no measured")
            visible = {k: v for k, v in sent.items() if v is not None}
            check(set(measured) == set(visible),
                  f"pose of frame {frame}: measured {sorted(measured)}, visible {sorted(visible)}")
            for k, v in visible.items():
                check(dist(measured[k], [c * 1e-3 for c in v]) <= 1e-9,
                      f"pose of frame {frame}: measured {k} {measured[k]}, sent {v} mm")
        d.stats_after(time.monotonic())
        check(d.models, "no model message after subscribing")
        check_model(d.models[0], pose, "m")
        check(d.encodings == {"msgpack"}, f"output encodings seen: {d.encodings}")
        d.stop()
        print("contract: output encoding msgpack, units m, measured_markers: poses (with "
              "measured), stats and model valid")


def run_pose_content(args, workdir, model_markers_rest, rest_joints, root):
    """output.pose_content ["angles"]: poses carry the schema's required fields
    and angles, nothing else of the optional parts, and still validate."""
    schema = json.loads((ROOT / "proto" / "pose.schema.json").read_text())
    required = set(schema["required"])
    inner = {k: set(schema["properties"][k]["required"]) for k in ("residual", "solver")}
    for enc in ("json", "msgpack"):
        with Daemon(args.fabrikd, workdir, output_encoding=enc, pose_content=["angles"]) as d:
            d.join()
            d.wait_for(lambda: d.models, ANSWER_TIMEOUT_S, "the model message after subscribing")
            coordinates = {c["name"] for c in d.models[0]["coordinates"]}
            hidden = sorted(model_markers_rest)[:2]
            for i in range(10):
                frame, t = 200 + i, i / 100.0
                markers = moved(model_markers_rest, root, t)
                sent = {k: (None if k in hidden and i % 2 else v) for k, v in markers.items()}
                d.send(json.dumps(marker_frame(frame, sent, t, "mm")).encode())
                pose = d.wait_pose(frame)  # validated against proto/pose.schema.json on arrival
                check_pose(pose, markers, frame, t, moved(rest_joints, root, t),
                           set(model_markers_rest), set(rest_joints),
                           expect_occluded=[k for k, v in sent.items() if v is None])
                check(set(pose) == required | {"time", "angles"},
                      f"pose of frame {frame} ({enc}) with pose_content [angles]: keys "
                      f"{sorted(pose)}")
                for k, keys in inner.items():
                    check(set(pose[k]) == keys, f"pose of frame {frame} ({enc}): {k} keys "
                          f"{sorted(pose[k])}, the schema requires {sorted(keys)}")
                check(set(pose["angles"]) <= coordinates and pose["angles"],
                      f"pose of frame {frame} ({enc}): angles {sorted(pose['angles'])}")
            d.stop()
    print("contract: output.pose_content [angles], JSON and MessagePack: poses carry the "
          "required fields and angles only, and validate")


def run_views(args, workdir, model_markers_rest, rest_joints, root):
    """output.views: a subscriber of a view's topic gets, per frame, a pose in
    the view's encoding with the view's parts, valid against the pose schema;
    stats count the view's subscriber and validate."""
    schema = json.loads((ROOT / "proto" / "pose.schema.json").read_text())
    required = set(schema["required"])
    views = [{"topic": "joints", "pose_content": ["angles"], "encoding": "msgpack", "units": "m"}]
    with Daemon(args.fabrikd, workdir, views=views) as d:
        d.join()
        view_sub = d.ctx.socket(zmq.SUB)
        view_sub.setsockopt(zmq.LINGER, 0)
        view_sub.setsockopt(zmq.SUBSCRIBE, b"joints")
        view_sub.connect(d.out_ep)
        try:
            deadline = time.monotonic() + 15.0
            frame = PROBE_BASE + 5000
            while not view_sub.poll(50):  # slow joiner
                check(time.monotonic() < deadline, "no view pose within 15 s of subscribing")
                d.send(json.dumps({"frame": frame, "markers": {}}).encode())
                frame += 1
                d.pump(0)
            while view_sub.poll(100):
                view_sub.recv_multipart()
            for i in range(10):
                frame, t = 500 + i, i / 100.0
                d.send(json.dumps(marker_frame(frame, moved(model_markers_rest, root, t), t,
                                               "mm")).encode())
                pose = d.wait_pose(frame)
                check(view_sub.poll(int(ANSWER_TIMEOUT_S * 1000)), f"no view pose of frame {frame}")
                topic, payload = view_sub.recv_multipart()
                check(topic == b"joints", f"view topic {topic!r}")
                view, enc = decode(payload)
                check(enc == "msgpack", f"view encoding {enc}, the view says msgpack")
                errors = list(d.pose_schema.iter_errors(view))
                check(not errors, f"view pose violates proto/pose.schema.json: {errors[:1]}")
                check(view["frame"] == frame, f"view of frame {view['frame']}, expected {frame}")
                check(set(view) == required | {"time", "angles"}, f"view keys {sorted(view)}")
                check(view["units"] == "m" and pose["units"] == "mm",
                      f"view units {view['units']}, pose units {pose['units']}")
                check(all(abs(view["joints"][k][a] - v[a] / 1000.0) < 1e-6
                          for k, v in pose["joints"].items() for a in range(3)),
                      "view joints are not the pose's in metres")
                # The same solve; JSON writes fixed decimals, MessagePack the double.
                check(set(view["angles"]) == set(pose["angles"]) and
                      all(abs(view["angles"][k] - v) < 0.01 for k, v in pose["angles"].items()),
                      "view angles differ from the pose's")
            stats = d.stats_after(time.monotonic())  # validated on arrival
            check(stats.get("views", {}).get("joints", {}).get("subscribers") == 1,
                  f"stats.views: {stats.get('views')}")
        finally:
            view_sub.close()
        d.stop()
    print("contract: output.views: a view's subscriber gets valid poses in its encoding, units and "
          "with its parts; stats.views valid")


def run_subjects(args, workdir, model_markers_rest, rest_joints, root):
    """Two subjects (docs/multi-subject.md): markers named SUBJECT:MARKER, and a
    frame with "subject"; each pose on pose/NAME with its subject, each model on
    model/NAME, stats with subjects: all valid against proto/."""
    names = ["Alice", "Bob"]
    with Daemon(args.fabrikd, workdir, subjects=names) as d:
        shift = {"Alice": 0.0, "Bob": 2000.0}  # mm along x: apart in the lab

        def both(t):
            markers = moved(model_markers_rest, root, t)
            return {f"{n}:{k}": [v[0] + shift[n], v[1], v[2]] for n in names
                    for k, v in markers.items()}

        deadline = time.monotonic() + 15.0
        frame = PROBE_BASE
        while not d.subject_poses:  # slow joiner
            check(time.monotonic() < deadline, "no pose/NAME within 15 s of starting fabrikd")
            d.send(json.dumps(marker_frame(frame, both(0.0))).encode())
            frame += 1
            d.pump(0.05)
        for i in range(10):
            frame, t = 300 + i, i / 100.0
            d.send(json.dumps(marker_frame(frame, both(t), t, "mm")).encode())
            for n in names:
                d.wait_for(lambda: (n, frame) in d.subject_poses, ANSWER_TIMEOUT_S,
                           f"pose/{n} of frame {frame}")
        bare = moved(model_markers_rest, root, 0.5)
        bob = {k: [v[0] + shift["Bob"], v[1], v[2]] for k, v in bare.items()}
        d.send(json.dumps(dict(marker_frame(400, bob, 0.5, "mm"), subject="Bob")).encode())
        d.wait_for(lambda: ("Bob", 400) in d.subject_poses, ANSWER_TIMEOUT_S, "pose/Bob of 400")
        check(("Alice", 400) not in d.subject_poses, "a frame with subject Bob answered for Alice")
        stats = d.stats_after(time.monotonic())
        check(set(stats.get("subjects", {})) == set(names), f"stats.subjects: {stats.get('subjects')}")
        d.wait_for(lambda: d.models, ANSWER_TIMEOUT_S, "model/NAME after subscribing")
        d.stop()
    print("contract: two subjects: poses on pose/NAME with subject, models, stats with subjects "
          "valid")


def main():
    global ANSWER_TIMEOUT_S
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fabrikd", required=True, help="path of the fabrikd executable")
    ap.add_argument("--frames", type=int, default=300, help="frames in the streaming check")
    ap.add_argument("--answer-timeout", type=float, default=3.0,
                    help="seconds a frame may take to be answered (sanitizer builds are slower)")
    args = ap.parse_args()
    ANSWER_TIMEOUT_S = args.answer_timeout
    args.fabrikd = os.path.abspath(args.fabrikd)  # the daemon runs in a temporary directory
    check(os.access(args.fabrikd, os.X_OK), f"{args.fabrikd} is not an executable")
    markers, joints, root = rest_positions(ROOT / "config/models/fullbody.json")
    with tempfile.TemporaryDirectory(prefix="fabrikd-contract-") as workdir:
        run_main(args, workdir, markers, joints, root)
        run_msgpack_metres(args, workdir, markers, joints, root)
        run_pose_content(args, workdir, markers, joints, root)
        run_views(args, workdir, markers, joints, root)
        run_subjects(args, workdir, markers, joints, root)
    print("contract: all checks passed")


if __name__ == "__main__":
    try:
        main()
    except CheckFailed as e:
        print(f"contract: FAILED: {e}", file=sys.stderr)
        sys.exit(1)
