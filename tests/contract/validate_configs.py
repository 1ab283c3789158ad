#!/usr/bin/python3
"""Checks proto/ against the contract's examples, validates config/default.json and every config/**/*.json whose "format" is
fabrikd-config/1 against proto/daemon-config.schema.json, and checks that a
few hand-made bad configs are rejected. With --fabrik, also the configs
`fabrik calibrate` writes (every keypoint template at its nominal lengths: no
recording needed). Exit code 1 on any failure."""
import argparse
import copy
import json
import pathlib
import subprocess
import sys
import tempfile

import jsonschema

ROOT = pathlib.Path(__file__).resolve().parents[2]


def bad_configs(good):
    """(name, config) pairs the schema must reject, each one mistake away from `good`."""
    def edit(fn):
        c = copy.deepcopy(good)
        fn(c)
        return c

    def drop(key):
        return lambda c: c.pop(key)

    def put(path, value):
        def fn(c):
            node = c
            for k in path[:-1]:
                node = node.setdefault(k, {})
            node[path[-1]] = value
        return fn

    return [
        ("missing format", edit(drop("format"))),
        ("missing model", edit(drop("model"))),
        ("wrong format", edit(put(["format"], "fabrikd-config/2"))),
        ("unknown top-level key", edit(put(["modle"], "x.json"))),
        ("model is a number", edit(put(["model"], 3))),
        ("inline model of another format", edit(put(["model"], {"format": "other"}))),
        ("unknown solver key", edit(put(["solver", "tolerance_m"], 0.1))),
        ("bad segment_fit", edit(put(["solver", "segment_fit"], "loose"))),
        ("max_iterations 0", edit(put(["solver", "max_iterations"], 0))),
        ("bad input mode", edit(put(["input", "mode"], "listen"))),
        ("bad input units", edit(put(["input", "units"], "cm"))),
        ("max_backlog_frames 0", edit(put(["input", "max_backlog_frames"], 0))),
        ("max_payload_bytes not an integer", edit(put(["input", "max_payload_bytes"], "1M"))),
        ("max_abs_coordinate_mm 0", edit(put(["input", "max_abs_coordinate_mm"], 0))),
        ("max_abs_coordinate_mm beyond 1e9", edit(put(["input", "max_abs_coordinate_mm"], 2e9))),
        ("zero_is_missing not a bool", edit(put(["input", "zero_is_missing"], "yes"))),
        ("bad output encoding", edit(put(["output", "encoding"], "cbor"))),
        ("endpoint without transport", edit(put(["output", "endpoint"], "127.0.0.1:5556"))),
        ("weight 0", edit(put(["targets", "default", "weight"], 0))),
        ("unknown marker entry key", edit(put(["targets", "markers", "RASI"], {"lvl": 1}))),
        ("track not a bool", edit(put(["targets", "markers", "RASI"], {"track": "no"}))),
        ("negative hold_s", edit(put(["occlusion", "hold_s"], -1))),
        ("stats interval 0", edit(put(["stats_interval_s"], 0))),
        ("stats interval 2 s", edit(put(["stats_interval_s"], 2))),
        ("bad log level", edit(put(["log_level"], "verbose"))),
        ("level 2^64 - 1", edit(put(["targets", "default", "level"], 2**64 - 1))),
        ("min_markers beyond 10000", edit(put(["outliers", "min_markers"], 20000))),
        ("subject_timeout_s without subjects", edit(put(["subject_timeout_s"], 1))),
        ("source_options without a source", edit(put(["input", "source_options"], {}))),
        ("unicast address as a NatNet multicast group",
         edit(put(["input"], {"source": "natnet://127.0.0.1",
                              "source_options": {"multicast_group": "10.0.0.5"}}))),
        # Python's `$` also matches before a last newline (ECMA-262's does not): a pattern
        # goes with "not": {"pattern": "\\n"} (a lookahead is outside the interoperable
        # subset: RE2-based validators refuse it), axes are an enum.
        ("NatNet multicast group with a trailing newline",
         edit(put(["input"], {"source": "natnet://127.0.0.1",
                              "source_options": {"multicast_group": "239.255.42.99\n"}}))),
        ("source axes with a trailing newline",
         edit(put(["input"], {"source": "qtm://127.0.0.1",
                              "source_options": {"axes": {"up": "+z\n"}}}))),
        ("subject name with a trailing newline",
         edit(lambda c: (c.clear(), c.update({"format": "fabrikd-config/1", "subjects": [
             {"name": "alice\n", "config": "alice.json"}]})))),
        ("NatNet multicast group with leading zeros",
         edit(put(["input"], {"source": "natnet://127.0.0.1",
                              "source_options": {"multicast_group": "239.001.1.1"}}))),
        # Ports as fabrikd's own check reads them (endpoint_check.cpp): were any text.
        *[(f"output endpoint {e!r}", edit(put(["output", "endpoint"], e))) for e in (
            "tcp://127.0.0.1:0", "tcp://127.0.0.1:65536", "tcp://127.0.0.1:000065536",
            "tcp://127.0.0.1", "tcp://[::1]", "tcp://127.0.0.1:55a", "tcp://127.0.0.1:",
            "tcp://127.0.0.1:5556\n", "ws://127.0.0.1:70000/poses",
            "ws://127.0.0.1/poses", "TCP://127.0.0.1:5556", "tpc://127.0.0.1:5556",
            "zmq://127.0.0.1:5556", "udp://127.0.0.1:5556")],
        # Port * is a bind's to choose (was left to fabrikd: the mode is a sibling key).
        ("input port * to connect",
         edit(put(["input"], {"endpoint": "tcp://127.0.0.1:*", "mode": "connect"}))),
        ("output ws port * to connect",
         edit(put(["output"], {"endpoint": "ws://127.0.0.1:*/poses", "mode": "connect"}))),
        # The sensors' world: axes as the loader reads them (were any string, any object).
        ("sensor world up not an axis", edit(put(["sensors", "world", "up"], "w"))),
        ("sensor heading axis not an axis",
         edit(put(["sensors", "world", "heading_from"], {"sensor": "torso_imu", "axis": "q"}))),
        ("sensor heading without its sensor",
         edit(put(["sensors", "world", "heading_from"], {"axis": "z"}))),
        ("sensor heading with an unknown key",
         edit(put(["sensors", "world", "heading_from"], {"sensor": "torso_imu", "axes": "z"}))),
        ("confidence beside subjects",
         {"format": "fabrikd-config/1", "subjects": [{"name": "A", "config": "a.json"}],
          "confidence": {"threshold": 0.5}}),
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--root", type=pathlib.Path, default=ROOT, help="repository root")
    ap.add_argument("--fabrik", type=pathlib.Path,
                    help="the fabrik program: validate what its calibrate writes too")
    args = ap.parse_args()
    schema = json.loads((args.root / "proto/daemon-config.schema.json").read_text())
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    validator = cls(schema)
    failures = []

    configs = sorted((args.root / "config").rglob("*.json"))
    checked = 0
    for path in configs:
        doc = json.loads(path.read_text())
        if path.name != "default.json" and not (
                isinstance(doc, dict) and doc.get("format") == "fabrikd-config/1"):
            continue  # models and experiment files have their own formats
        checked += 1
        errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))
        for e in errors:
            failures.append(f"{path}: at /{'/'.join(map(str, e.absolute_path))}: {e.message}")
    if not any(p.name == "default.json" for p in configs):
        failures.append("config/default.json is missing")

    # The message schemas must be valid schemas and accept the contract's own examples.
    examples = {
        "markers": {"frame": 1042, "time": 17.366, "units": "mm",
                    "markers": {"R.ASIS": [617.2, 1055.3, 170.8], "L.ASIS": None}},
        "pose": {"frame": 1042, "time": 17.366, "units": "mm",
                 "joints": {"r_hip": [1, 2, 3]}, "markers": {"R.ASIS": [1, 2, 3]},
                 "occluded": ["L.ASIS"],
                 "residual": {"rms": 4.1, "max": 9.7, "worst": "R.Heel", "count": 40},
                 "solver": {"status": "converged", "iterations": 6, "solve_us": 8.3}},
        "stats": {"uptime_s": 1.0, "frames_in": 0, "frames_out": 0, "frames_dropped": 0,
                  "decode_errors": 0, "unknown_markers": 0,
                  "solve_us": {"p50": 0, "p99": 0, "max": 0},
                  "queue_latency_us": {"p50": 0, "p99": 0}},
    }
    for topic, example in examples.items():
        s = json.loads((args.root / f"proto/{topic}.schema.json").read_text())
        c = jsonschema.validators.validator_for(s)
        c.check_schema(s)
        for e in c(s).iter_errors(example):
            failures.append(f"proto/{topic}.schema.json rejects the contract example: {e.message}")

    default = json.loads((args.root / "config/default.json").read_text())
    for name, doc in bad_configs(default):
        if validator.is_valid(doc):
            failures.append(f"bad config accepted by the schema: {name}")
    # Optional fields at values the daemon accepts must pass too.
    good = copy.deepcopy(default)
    good.setdefault("input", {}).update({"max_abs_coordinate_mm": 5000, "zero_is_missing": False})
    for e in validator.iter_errors(good):
        failures.append(f"valid input limits rejected by the schema: {e.message}")
    natnet = copy.deepcopy(default)
    natnet["input"] = {"source": "natnet://127.0.0.1",
                       "source_options": {"multicast_group": "239.255.42.99"}}
    for e in validator.iter_errors(natnet):
        failures.append(f"Motive's default multicast group rejected by the schema: {e.message}")
    subjects = {"format": "fabrikd-config/1",
                "subjects": [{"name": "alice", "config": "alice.json"}]}
    for e in validator.iter_errors(subjects):
        failures.append(f"a multi-subject config rejected by the schema: {e.message}")
    for endpoint in ("tcp://127.0.0.1:5556", "tcp://127.0.0.1:05556", "tcp://*:*",
                     "tcp://[::1]:65535", "tcp://127.0.0.1:6000;127.0.0.1:5556",
                     "tcp://127.0.0.1:000022607", "ws://127.0.0.1:8080/poses", "ws://host:1",
                     "ipc:///tmp/fabrikd-poses", "inproc://poses", "norm://127.0.0.1:5556",
                     "tipc://{5560,0,0}", "vmci://1:5556", "epgm://eth0;239.192.1.1:5555"):
        ported = copy.deepcopy(default)
        ported["output"]["endpoint"] = endpoint
        for e in validator.iter_errors(ported):
            failures.append(f"endpoint {endpoint!r} fabrikd takes rejected by the schema: {e.message}")
    for side, endpoint, mode in (("input", "tcp://127.0.0.1:*", "bind"),
                                 ("output", "tcp://*:*", None),
                                 ("input", "tcp://127.0.0.1:5555", "connect"),
                                 ("output", "ipc:///tmp/fabrikd:*", "connect")):
        moded = copy.deepcopy(default)
        moded[side] = {"endpoint": endpoint, **({"mode": mode} if mode else {})}
        for e in validator.iter_errors(moded):
            failures.append(f"{side} {endpoint!r} ({mode}) fabrikd takes rejected: {e.message}")
    sensors = copy.deepcopy(default)
    sensors["sensors"] = {"world": {"rotation_deg": [-90, 0, 0], "up": "y",
                                    "heading_from": {"sensor": "torso_imu", "axis": "-z"}},
                          "orientations": {"torso_imu": {"segment": "torso"}}}
    for e in validator.iter_errors(sensors):
        failures.append(f"a sensors section the loader takes rejected by the schema: {e.message}")
    sensors["sensors"]["world"]["heading_from"] = None
    for e in validator.iter_errors(sensors):
        failures.append(f"a null heading_from rejected by the schema: {e.message}")
    # Every axis the loader takes (signed or not, lower case) passes the enums.
    for up, forward in (("+z", "-y"), ("z", "x"), ("-x", "+y")):
        axes = copy.deepcopy(default)
        axes["input"] = {"source": "qtm://127.0.0.1",
                         "source_options": {"axes": {"up": up, "forward": forward}}}
        for e in validator.iter_errors(axes):
            failures.append(f"source axes up {up}, forward {forward} rejected: {e.message}")

    # What users run: a config `fabrik calibrate` writes (it once wrote a solver key the
    # schema did not have, subtree_carry).
    written = 0
    if args.fabrik:
        with tempfile.TemporaryDirectory() as tmp:
            for template in sorted((args.root / "config/templates").glob("*.json")):
                if json.loads(template.read_text()).get("kind") != "keypoints":
                    continue
                out = pathlib.Path(tmp) / template.name
                try:
                    run = subprocess.run([str(args.fabrik), "calibrate", "--template",
                                          str(template), "--nominal", "--output", str(out)],
                                         capture_output=True, text=True, timeout=120)
                except (OSError, subprocess.TimeoutExpired) as e:
                    failures.append(f"fabrik calibrate --template {template.name} --nominal: {e}")
                    continue
                if run.returncode != 0:
                    failures.append(f"fabrik calibrate --template {template.name} --nominal "
                                    f"failed ({run.returncode}): {run.stderr.strip()}")
                    continue
                written += 1
                for e in validator.iter_errors(json.loads(out.read_text())):
                    failures.append(f"fabrik calibrate --template {template.name} --nominal writes "
                                    f"a config the schema rejects: at "
                                    f"/{'/'.join(map(str, e.absolute_path))}: {e.message}")
        if written == 0:
            failures.append("no keypoint template under config/templates: nothing calibrated")

    if failures:
        print("validate_configs: FAILED", file=sys.stderr)
        for f in failures:
            print("  " + f, file=sys.stderr)
        return 1
    print(f"validate_configs: {checked} config(s) valid, "
          f"{len(bad_configs(default))} bad configs rejected, "
          f"{written} calibrated config(s) valid")
    return 0


if __name__ == "__main__":
    sys.exit(main())
