"""Forward kinematics of a calibrated fabrikd model (what `fabrik calibrate` writes),
reimplemented in numpy from src/solver/{model,model_builder,joint_angles,posture}.cpp and
src/config/model_loader.cpp, plus .trc/.mot readers. A library for ik_ls.py (docs/least-squares-ik.md);
verify_fk.py checks it against `fabrik solve`.

Convention: each joint's angles are the Cardan decomposition E = Rz(a_z) Rx(a_x) Ry(a_y) of the
child's anatomical frame relative to the parent's:  R_child = R_parent J_parent E J_child^T,
J the anatomical frame (columns x, y, z) in the segment frame. Child base = parent base +
R_parent p_local(joint point). Lengths in mm here (the config's unit).
The root is parameterised as the Cardan angles of its anatomical frame in the reference frame
(lab_axes turned onto OpenSim's ground) plus its base position in the lab (mm).
"""
import json
import numpy as np

AX = {"z": 0, "x": 1, "y": 2}  # Cardan index of an axis letter


def rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def rot_zxy(a):
    return rz(a[0]) @ rx(a[1]) @ ry(a[2])


def rodrigues(a, t):
    a = np.asarray(a, float) / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


def cardan_zxy(r):
    b = np.arcsin(np.clip(r[2, 1], -1, 1))
    return np.array([np.arctan2(-r[0, 1], r[1, 1]), b, np.arctan2(-r[2, 0], r[2, 2])])


def nearest_rotation(m):
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def lab_matrix(lab):
    def axis(s):
        v = np.zeros(3)
        v["xyz".index(s[1])] = 1.0 if s[0] == "+" else -1.0
        return v
    up, fwd = axis(lab.get("up", "+y")), axis(lab.get("forward", "+x"))
    return np.vstack([fwd, up, np.cross(fwd, up)])  # rows: reference X, Y, Z in the lab


class Model:
    def __init__(self, cfg_path):
        cfg = json.load(open(cfg_path))
        m = cfg["model"]
        assert m["units"] == "mm"
        self.cfg = cfg
        self.root_rest = np.array(m["root_position"], float)
        self.lab = lab_matrix(m.get("lab_axes", {}))
        segs = m["segments"]
        self.names = [s["name"] for s in segs]
        self.idx = {n: i for i, n in enumerate(self.names)}
        self.parent = [self.idx.get(s.get("parent"), -1) if s.get("parent") else -1 for s in segs]
        for i, p in enumerate(self.parent):
            assert p < i, "segments not in topological order"
        self.J = []
        for s in segs:
            f = s.get("frame")
            if f is None:
                self.J.append(np.eye(3))
                continue
            ax = {k: np.array(f[k], float) / np.linalg.norm(f[k]) for k in "xyz" if k in f}
            for k, (a, b) in {"x": ("y", "z"), "y": ("z", "x"), "z": ("x", "y")}.items():
                if k not in ax:
                    ax[k] = np.cross(ax[a], ax[b])
            self.J.append(nearest_rotation(np.column_stack([ax["x"], ax["y"], ax["z"]])))
        # Points: the base of each child in its parent's frame.
        self.base_in_parent = [None] * len(segs)
        for i, s in enumerate(segs):
            if self.parent[i] >= 0:
                self.base_in_parent[i] = np.array(segs[self.parent[i]]["points"][s["base"]], float)
        self.base_name = [s["base"] for s in segs]
        self.points = [{k: np.array(v, float) for k, v in s.get("points", {}).items()} for s in segs]
        # Markers
        self.marker_names, self.marker_seg, ml = [], [], []
        for i, s in enumerate(segs):
            for k, v in s.get("markers", {}).items():
                self.marker_names.append(k)
                self.marker_seg.append(i)
                ml.append(v)
        self.marker_local = np.array(ml, float)
        self.marker_seg = np.array(self.marker_seg)
        t = cfg.get("targets", {})
        dw = t.get("default", {}).get("weight", 1.0)
        self.marker_w = np.array([t.get("markers", {}).get(n, {}).get("weight", dw)
                                  for n in self.marker_names])
        # Joints: type, ranges (rad), rest angles.
        self.jtype, self.lo, self.hi, self.rest = [], [], [], []
        for i, s in enumerate(segs):
            j = s.get("joint", {})
            typ = j.get("type", "free") if i > 0 else "free"
            rest = cardan_zxy(self.J[self.parent[i]].T @ self.J[i]) if i > 0 else np.zeros(3)
            moves = {"free": [1, 1, 1], "ball": [1, 1, 1], "universal": [1, 1, 0],
                     "hinge": [1, 0, 0], "fixed": [0, 0, 0]}[typ]
            lo, hi = np.array([-np.pi, -np.pi / 2, -np.pi]), np.array([np.pi, np.pi / 2, np.pi])
            rd = j.get("range_deg", {})
            for a, k in AX.items():
                if not moves[k]:
                    lo[k] = hi[k] = rest[k]
                elif a in rd:
                    lo[k], hi[k] = np.radians(rd[a][0]), np.radians(rd[a][1])
                if moves[k] and k == 1:
                    lo[k], hi[k] = max(lo[k], -np.pi / 2 + 0.01), min(hi[k], np.pi / 2 - 0.01)
            self.jtype.append(typ)
            self.lo.append(lo)
            self.hi.append(hi)
            self.rest.append(rest)
        self.ancestor = np.zeros((len(segs), len(segs)), bool)  # [a, s]: a is s or an ancestor of s
        for s in range(len(segs)):
            a = s
            while a >= 0:
                self.ancestor[a, s] = True
                a = self.parent[a]
        # Coordinates
        self.coords = []
        for name, c in sorted(m.get("coordinates", {}).items()):
            sign = c.get("sign", 1.0)
            if "point" in c:
                seg = next(i for i, p in enumerate(self.points) if c["point"] in p)
                self.coords.append(dict(name=name, kind="t", seg=seg, p=self.points[seg][c["point"]],
                                        axis="xyz".index(c["axis"]), sign=sign,
                                        offset=c.get("offset", 0.0)))
            else:
                seg = self.idx[c["segment"]]
                rel = c.get("relative_to")
                ref = -1 if rel == "world" else (self.idx[rel] if rel else self.parent[seg])
                self.coords.append(dict(name=name, kind="r", seg=seg, ref=ref, angle=AX[c["axis"]],
                                        sign=sign, offset=np.radians(c.get("offset_deg", 0.0))))

    # angles: (S, 3) array; row 0 = root Cardan angles in the reference frame; root_base mm (lab)
    def fk(self, angles, root_base):
        S = len(self.names)
        self._angles = angles
        R = np.empty((S, 3, 3))
        B = np.empty((S, 3))
        R[0] = self.lab.T @ rot_zxy(angles[0]) @ self.J[0].T
        B[0] = root_base
        hinge_axes = getattr(self, "hinge_axes", {})
        for s in range(1, S):
            p = self.parent[s]
            if s in hinge_axes:  # a hinge about an oblique axis (parent's anatomical frame)
                E = rodrigues(hinge_axes[s], angles[s][0] - self.rest[s][0]) @ rot_zxy(self.rest[s])
            else:
                E = rot_zxy(angles[s])
            R[s] = R[p] @ self.J[p] @ E @ self.J[s].T
            B[s] = B[p] + R[p] @ self.base_in_parent[s]
        return R, B

    def markers_world(self, R, B):
        return np.einsum("mij,mj->mi", R[self.marker_seg], self.marker_local) + B[self.marker_seg]

    def coordinate_values(self, R, B):
        out = {}
        for c in self.coords:
            if c["kind"] == "t":
                v = self.lab @ (R[c["seg"]] @ c["p"] + B[c["seg"]])
                out[c["name"]] = c["sign"] * (v[c["axis"]] * 1e-3 + c["offset"])  # metres
            else:
                child = R[c["seg"]] @ self.J[c["seg"]]
                rel = (R[c["ref"]] @ self.J[c["ref"]]).T @ child if c["ref"] >= 0 else self.lab @ child
                out[c["name"]] = c["sign"] * (cardan_zxy(rel)[c["angle"]] + c["offset"])
        for s in getattr(self, "hinge_axes", {}):  # an oblique hinge reports its own angle, as OpenSim
            for c in self.coords:
                if c["kind"] == "r" and c["seg"] == s and c["ref"] == self.parent[s] and c["angle"] == 0:
                    out[c["name"]] = c["sign"] * self._angles[s][0]
        return out


def read_trc(path):
    lines = open(path).read().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n.strip()]
    rows = []
    for ln in lines[5:]:
        if not ln.strip():
            continue
        f = ln.split("\t")
        vals = [float(x) if x.strip() else np.nan for x in f[2:2 + 3 * len(names)]]
        vals += [np.nan] * (3 * len(names) - len(vals))
        rows.append((float(f[1]), vals))
    t = np.array([r[0] for r in rows])
    X = np.array([r[1] for r in rows]).reshape(len(rows), len(names), 3)
    return names, t, X


def read_mot(path):
    lines = open(path).read().splitlines()
    h = next(i for i, l in enumerate(lines) if l.strip() == "endheader")
    deg = any("inDegrees=yes" in l for l in lines[:h])
    cols = lines[h + 1].split()
    data = np.array([[float(x) for x in l.split()] for l in lines[h + 2:] if l.strip()])
    return cols, data, deg
