#!/usr/bin/env python3
"""Writes config/templates/{halpe26,coco17,blazepose33}.json: the keypoint templates
(docs/keypoints.md). One description of a body, three keypoint sets; run it after
editing a range or a rest vector so the three stay consistent."""
import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "config", "templates")

# Joint ranges: the AAOS averages (Greene & Heckman 1994) as config/templates/gait2354.json
# gives them; a left joint mirrors the right one's x and y.
def mirror(r):
    out = dict(r)
    for k in ("x", "y"):
        if k in r:
            out[k] = [-r[k][1], -r[k][0]]
    return out

HIP_R = {"z": [-30, 120], "x": [-45, 30], "y": [-45, 45]}
KNEE = {"z": [-140, 5]}
ANKLE_R = {"z": [-50, 30], "x": [-25, 35]}
SHOULDER_R = {"z": [-60, 180], "x": [-90, 90], "y": [-90, 70]}
ELBOW = {"z": [-5, 150]}
ELBOW_PROSUP_R = {"z": [-5, 150], "x": [-10, 10], "y": [-90, 90]}
WRIST_R = {"z": [-70, 80], "x": [-20, 30]}
NECK = {"z": [-45, 45], "x": [-45, 45], "y": [-60, 60]}
# Flexion-extension held: the keypoints cannot tell the pelvis's tilt from the trunk's
# flexion (docs/keypoints.md), so pelvis_tilt carries both.
LUMBAR = {"z": [-1, 1], "x": [-35, 35], "y": [-45, 45]}

def joint(kind, ranges, desc):
    return {"type": kind, "range_deg": ranges, "description": desc}

def kp(name, rest, target="joint", rest_from=None, optional=False):
    p = {"at": name, "target": target, "rest": rest}
    if rest_from:
        p["rest_from"] = rest_from
    if optional:
        p["optional"] = True
    return p

def side_names(style, side):
    """Keypoint names per style: Pose2Sim's RKnee, MediaPipe's right_knee."""
    if style == "pose2sim":
        S = "R" if side == "r" else "L"
        return lambda part: S + part
    word = "right_" if side == "r" else "left_"
    snake = {"Hip": "hip", "Knee": "knee", "Ankle": "ankle", "Heel": "heel",
             "BigToe": "foot_index", "Shoulder": "shoulder", "Elbow": "elbow",
             "Wrist": "wrist", "Index": "index", "Pinky": "pinky", "Thumb": "thumb",
             "Eye": "eye", "Ear": "ear"}
    return lambda part: word + snake[part]

def build(name, style, feet, hands, neck_keypoint, head_top, hip_keypoint, face):
    z = 1  # right is +z
    segs = []
    pelvis_pts = {"pelvis_origin": {"midpoint": ["r_hip", "l_hip"],
                                    "description": "the hip centres' midpoint"}}
    for s, sign in (("r", 1), ("l", -1)):
        n = side_names(style, s)
        pelvis_pts[f"{s}_hip"] = kp(n("Hip"), [0, 0, 90 * sign])
    pelvis_pts["lumbar"] = {"rest": [-30, 150, 0],
                            "description": "L5/S1, which no keypoint sees: fixed where "
                                           "gait2354.json puts it relative to the hip centres"}
    if hip_keypoint:
        pelvis_pts["hip_centre"] = kp("Hip", [0, 1, 0], target="point", optional=True)
        pelvis_pts["hip_centre"]["description"] = ("Pose2Sim's Hip: between the hip centres "
                                                    "(its small distance from them is measured)")
    segs.append({"name": "pelvis", "base": "pelvis_origin", "points": pelvis_pts})
    torso_pts = {}
    if neck_keypoint:
        torso_pts["neck"] = kp("Neck", [0, 480, 0], rest_from="pelvis_origin")
    else:
        torso_pts["neck"] = {"midpoint": ["r_shoulder", "l_shoulder"], "rest": [0, 480, 0],
                             "rest_from": "pelvis_origin",
                             "description": "no neck keypoint: between the shoulders"}
    for s, sign in (("r", 1), ("l", -1)):
        n = side_names(style, s)
        torso_pts[f"{s}_shoulder"] = kp(n("Shoulder"), [0, 0, 170 * sign], rest_from="neck")
    segs.append({"name": "torso", "parent": "pelvis", "base": "lumbar", "points": torso_pts,
                 "joint": joint("ball", LUMBAR,
                                "lumbar: lateral bending 35 and rotation 45 (AAOS thoracolumbar); "
                                "flexion-extension held, since pelvis tilt and trunk flexion are "
                                "one rotation to the keypoints (pelvis_tilt reads both)")})
    head_pts = {}
    if head_top:
        head_pts["head_top"] = kp("Head", [0, 300, 0], target="point")
    nose = "Nose" if style == "pose2sim" else "nose"
    head_pts["nose_tip"] = kp(nose, [90, 220, 0], target="point")
    if face:
        for s, sign in (("r", 1), ("l", -1)):
            n = side_names(style, s)
            head_pts[f"{s}_eye"] = kp(n("Eye"), [75, 250, 33 * sign], target="point")
            head_pts[f"{s}_ear"] = kp(n("Ear"), [-10, 230, 75 * sign], target="point")
    segs.append({"name": "head", "parent": "torso", "base": "neck", "points": head_pts,
                 "joint": joint("ball", NECK, "AAOS cervical: flexion 45, extension 45, "
                                "lateral flexion 45, rotation 60")})
    for s, sign in (("r", 1), ("l", -1)):
        n = side_names(style, s)
        m = (lambda r: r) if s == "r" else mirror
        segs.append({"name": f"{s}_humerus", "parent": "torso", "base": f"{s}_shoulder",
                     "points": {f"{s}_elbow": kp(n("Elbow"), [0, -290, 0])},
                     "joint": joint("ball", m(SHOULDER_R), "humerus relative to the trunk (no "
                                    "clavicle keypoints): AAOS flexion 180, extension 60, internal "
                                    "rotation 70, external rotation 90; the arm's axial rotation "
                                    "shows only while the elbow is bent")})
        fore = {f"{s}_wrist": kp(n("Wrist"), [0, -250, 0])}
        if hands:
            segs.append({"name": f"{s}_forearm", "parent": f"{s}_humerus", "base": f"{s}_elbow",
                         "points": fore,
                         "joint": joint("ball", m(ELBOW_PROSUP_R),
                                        "elbow flexion 150 (AAOS) with 5 of hyperextension; "
                                        "pronation-supination 90 each way, seen through the hand's "
                                        "keypoints; carrying angle within 10")})
            segs.append({"name": f"{s}_hand", "parent": f"{s}_forearm", "base": f"{s}_wrist",
                         "points": {f"{s}_index": kp(n("Index"), [10, -80, -5 * sign], "point"),
                                    f"{s}_pinky": kp(n("Pinky"), [-20, -70, -5 * sign], "point"),
                                    f"{s}_thumb": kp(n("Thumb"), [35, -45, -10 * sign], "point")},
                         "joint": joint("universal", m(WRIST_R),
                                        "wrist: AAOS flexion 80, extension 70, ulnar deviation 30, "
                                        "radial 20; axial rotation held (it is the forearm's)")})
        else:
            segs.append({"name": f"{s}_forearm", "parent": f"{s}_humerus", "base": f"{s}_elbow",
                         "points": fore,
                         "joint": joint("hinge", ELBOW, "elbow flexion 150 (AAOS) with 5 of "
                                        "hyperextension; a single wrist keypoint cannot show "
                                        "pronation-supination")})
    for s, sign in (("r", 1), ("l", -1)):
        n = side_names(style, s)
        m = (lambda r: r) if s == "r" else mirror
        segs.append({"name": f"{s}_thigh", "parent": "pelvis", "base": f"{s}_hip",
                     "points": {f"{s}_knee": kp(n("Knee"), [0, -420, 0])},
                     "joint": joint("ball", m(HIP_R), "AAOS: flexion 120, extension 30, "
                                    "abduction 45, adduction 30, rotation 45 each way; the thigh's "
                                    "axial rotation shows only while the knee is bent")})
        segs.append({"name": f"{s}_shank", "parent": f"{s}_thigh", "base": f"{s}_knee",
                     "points": {f"{s}_ankle": kp(n("Ankle"), [0, -400, 0])},
                     "joint": joint("hinge", KNEE, "knee flexion 140, hyperextension 5 "
                                    "(config/templates/gait2354.json)")})
        if feet == "none":
            continue
        pts = {f"{s}_heel": kp(n("Heel"), [-50, -60, 0], "point"),
               f"{s}_toe": kp(n("BigToe"), [150, -70, -20 * sign if feet == "halpe" else 0],
                              "point")}
        if feet == "halpe":
            pts[f"{s}_small_toe"] = kp(n("SmallToe") if style == "pose2sim" else "",
                                       [120, -70, 35 * sign], "point")
            segs.append({"name": f"{s}_foot", "parent": f"{s}_shank", "base": f"{s}_ankle",
                         "points": pts,
                         "joint": joint("universal", m(ANKLE_R),
                                        "dorsiflexion 30, plantarflexion 50, inversion 35, "
                                        "eversion 25 (gait2354.json); axial rotation held")})
        else:
            segs.append({"name": f"{s}_foot", "parent": f"{s}_shank", "base": f"{s}_ankle",
                         "points": pts,
                         "joint": joint("hinge", {"z": ANKLE_R["z"]},
                                        "dorsiflexion 30, plantarflexion 50; heel and toe are "
                                        "on one line with the ankle's plane, so inversion cannot "
                                        "be seen: a hinge")})
    coords = {
        "pelvis_tilt": {"segment": "pelvis", "axis": "z", "relative_to": "world"},
        "pelvis_list": {"segment": "pelvis", "axis": "x", "relative_to": "world"},
        "pelvis_rotation": {"segment": "pelvis", "axis": "y", "relative_to": "world"},
        "pelvis_tx": {"point": "pelvis_origin", "axis": "x"},
        "pelvis_ty": {"point": "pelvis_origin", "axis": "y"},
        "pelvis_tz": {"point": "pelvis_origin", "axis": "z"},
    }
    for s in ("r", "l"):
        sg = {} if s == "r" else {"sign": -1}
        coords[f"hip_flexion_{s}"] = {"segment": f"{s}_thigh", "axis": "z"}
        coords[f"hip_adduction_{s}"] = {"segment": f"{s}_thigh", "axis": "x", **sg}
        coords[f"hip_rotation_{s}"] = {"segment": f"{s}_thigh", "axis": "y", **sg}
        coords[f"knee_angle_{s}"] = {"segment": f"{s}_shank", "axis": "z"}
        if feet != "none":
            coords[f"ankle_angle_{s}"] = {"segment": f"{s}_foot", "axis": "z"}
        if feet == "halpe":
            coords[f"subtalar_angle_{s}"] = {"segment": f"{s}_foot", "axis": "x", **sg}
    for s in ("r", "l"):
        sg = {} if s == "r" else {"sign": -1}
        coords[f"arm_flex_{s}"] = {"segment": f"{s}_humerus", "axis": "z"}
        coords[f"arm_add_{s}"] = {"segment": f"{s}_humerus", "axis": "x", **sg}
        coords[f"arm_rot_{s}"] = {"segment": f"{s}_humerus", "axis": "y", **sg}
        coords[f"elbow_flex_{s}"] = {"segment": f"{s}_forearm", "axis": "z"}
        if hands:
            coords[f"pro_sup_{s}"] = {"segment": f"{s}_forearm", "axis": "y", **sg}
            coords[f"wrist_flex_{s}"] = {"segment": f"{s}_hand", "axis": "z"}
            coords[f"wrist_dev_{s}"] = {"segment": f"{s}_hand", "axis": "x", **sg}
    coords["lumbar_bending"] = {"segment": "torso", "axis": "x", "relative_to": "pelvis"}
    coords["lumbar_rotation"] = {"segment": "torso", "axis": "y", "relative_to": "pelvis"}
    return {"format": "fabrikd-template/1", "kind": "keypoints", "name": name, "units": "mm",
            "segments": segs, "coordinates": coords}

TEMPLATES = {
    "halpe26": (build("halpe26", "pose2sim", "halpe", False, True, True, True, False),
                "Markerless keypoints as Pose2Sim writes HALPE_26 (and Body25-style) TRC files: "
                "RHip RKnee RAnkle RBigToe RSmallToe RHeel, Neck Head Nose, RShoulder RElbow "
                "RWrist, the left side, and Hip if present. Keypoints land on joint centres "
                "(\"target\": \"joint\") or segment points (\"point\"); lengths come from "
                "`fabrik calibrate --trial` (any movement), directions from the rest vectors "
                "(standing, OpenSim axes x anterior, y up, z right; mm are nominal lengths, used "
                "by `fabrik synth --keypoints`). What the keypoints cannot determine: "
                "docs/keypoints.md."),
    "coco17": (build("coco17", "pose2sim", "none", False, False, False, False, True),
               "Markerless keypoints of COCO-17 with Pose2Sim's names (RHip RKnee RAnkle, "
               "RShoulder RElbow RWrist, the left side, Nose, REye LEye REar LEar): no feet, no "
               "neck (the point between the shoulders stands in), so no ankle angles. See "
               "halpe26.json and docs/keypoints.md."),
    "blazepose33": (build("blazepose33", "mediapipe", "blaze", True, False, False, False, True),
                    "Markerless keypoints of MediaPipe BlazePose (33 landmarks, MediaPipe's "
                    "names: right_hip, right_knee, right_ankle, right_heel, right_foot_index, "
                    "right_shoulder, right_elbow, right_wrist, right_index, right_pinky, "
                    "right_thumb, nose, eyes, ears; the inner/outer eye and mouth landmarks are "
                    "not tracked). The hand's keypoints show the forearm's pronation. See "
                    "halpe26.json and docs/keypoints.md."),
}

for name, (t, desc) in TEMPLATES.items():
    t["description"] = desc
    ordered = {k: t[k] for k in ("format", "kind", "name", "description", "units", "segments",
                                 "coordinates")}
    with open(os.path.join(OUT, name + ".json"), "w") as f:
        json.dump(ordered, f, indent=2)
        f.write("\n")
    print("wrote", name)
