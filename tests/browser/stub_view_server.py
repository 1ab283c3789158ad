#!/usr/bin/python3
"""A stand-in for `fabrik view`, for developing and testing the page
(src/view/web) without fabrikd: the same URL table and the same WebSocket
messages, with a synthetic walking subject.

    stub_view_server.py [--listen 127.0.0.1:0] [--rate-hz 60] [--source-hz 250]
                        [--up y|z] [--synthetic-trial SECONDS] [--pose EP]

Prints `stub_view_server: http://HOST:PORT/` once it listens. Commands on
stdin, one a line, change what it sends to every client:
    live     poses, stats and status "ok" (the start)
    stall    no poses; stats go on; status "stalled" after 1 s
    silent   nothing at all (the page must notice by itself)
    garbage  undecodable messages instead of poses; status "garbage"
    source-down  stats carry a vendor source (`source`, as fabrikd's with
             input.source) that is not connected, QTM refusing: use with stall,
             as QTM down means no poses
    source-up    the source connected (reconnected after source-down)
    source-none  stats without `source` again, as on plain ZeroMQ input (the start)
    no-targets   poses on which no marker is measured, as fabrikd sends them when
             QTM sends only invalid positions or names none of the config's
             markers: all occluded, solver status no_targets, the posture
             standing still (the one when the command came); `live` resumes
    held     the same with every marker held (occlusion.hold_s): status
             converged, all occluded
    outliers every visible marker rejected as an outlier: no_targets, the
             markers measured and not occluded
    waiting  no poses and no stats (fabrikd not there), status "waiting" with
             fabrik view's message "waiting for poses from tcp://..."
    quit
--start-mode MODE starts in MODE instead of live. --max-clients N: one client
more is sent a status "rejected" (fabrik view's words) and closed.
With --synthetic-trial S it sends, on connect, one `trial` message of S seconds of
poses at 50 Hz and nothing live. With --pose EP it relays a real fabrikd's
`pose`, `stats` (and `model`, once fabrikd publishes it; until then a model
without bones made from the first pose) at --rate-hz, newest pose wins:
the page on live poses before `fabrik view` exists. Also answers as
`stub_view_server.py view --pose EP --listen H:P [--rate-hz N]`, the
command line of `fabrik view`.

HTTP: GET only; `/` and `/index.html`, `/app/<name>.js|.css` (flat, names
[A-Za-z0-9_-]+) from src/view/web, `/three/build/three.module.js` and
`/three/examples/jsm/controls/OrbitControls.js` from Debian's libjs-three;
anything else 404. WebSocket: a minimal RFC 6455 server (text frames out,
client frames read and dropped, close answered); Python's standard library
only.
"""
import argparse
import base64
import hashlib
import http.server
import json
import math
import os
import re
import struct
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
WEB_DIR = os.path.normpath(os.path.join(HERE, '..', '..', 'src', 'view', 'web'))
THREE_DIR = '/usr/share/javascript/three'
THREE_FILES = {
    '/three/build/three.module.js': 'build/three.module.js',
    '/three/examples/jsm/controls/OrbitControls.js': 'examples/jsm/controls/OrbitControls.js',
}
TYPES = {'.html': 'text/html; charset=utf-8', '.js': 'text/javascript; charset=utf-8',
         '.css': 'text/css; charset=utf-8'}
WS_GUID = '258EAFA5-E914-47DA-95CA-C5AB0DC85B11'
# The vendor source of source-down/up, and fabrikd's words when QTM is not
# running (the markup in it checks that the page shows it as text).
SOURCE_URL = 'qtm://127.0.0.1:22223'
SOURCE_ERROR = ('QTM at 127.0.0.1:22223: cannot connect (Connection refused); is QTM running with its '
                'RT server on? <b>Its</b> little-endian RT port is base + 1, 22223 by default')
MAX_CLIENT_MESSAGE = 4096

# --- The synthetic subject: a 15-segment body, 45 markers, walking in x. ----

# name, parent, base joint, distal points {joint: local}, markers {name: local}
# (local: the segment's frame, x anterior, y up, z right; mm).
RIGHT = [
    ('r_thigh', 'pelvis', 'r_hip', {'r_knee': (0, -420, 0)},
     {'RTHI': (0, -220, 70), 'RTHF': (60, -200, 0), 'RKNE': (0, -420, 55)}),
    ('r_shank', 'r_thigh', 'r_knee', {'r_ankle': (0, -400, 0)},
     {'RTIB': (0, -200, 60), 'RSHF': (50, -180, 0), 'RANK': (0, -400, 45)}),
    ('r_foot', 'r_shank', 'r_ankle', {'r_toe': (150, -60, 10)},
     {'RHEE': (-60, -50, 0), 'RTOE': (150, -50, 10), 'RMT5': (110, -55, 45)}),
    ('r_upper_arm', 'torso', 'r_shoulder', {'r_elbow': (0, -290, 0)},
     {'RUPA': (0, -150, 50), 'RELB': (0, -290, 40)}),
    ('r_forearm', 'r_upper_arm', 'r_elbow', {'r_wrist': (0, -250, 0)},
     {'RFRA': (0, -120, 40), 'RWRA': (20, -250, 30), 'RWRB': (-20, -250, 30)}),
    ('r_hand', 'r_forearm', 'r_wrist', {'r_hand_tip': (0, -180, 0)},
     {'RFIN': (0, -160, 20), 'RHAN': (0, -80, 30)}),
]


def _mirror(seg):
    name, parent, base, points, markers = seg
    flip = lambda s: 'l' + s[1:] if s.startswith('r_') else s  # noqa: E731
    return (flip(name), flip(parent), flip(base),
            {flip(k): (x, y, -z) for k, (x, y, z) in points.items()},
            {'L' + k[1:]: (x, y, -z) for k, (x, y, z) in markers.items()})


SEGMENTS = [
    ('pelvis', None, 'pelvis_origin',
     {'r_hip': (-60, -80, 85), 'l_hip': (-60, -80, -85), 'lumbosacral': (-80, 60, 0)},
     {'RASI': (20, 20, 120), 'LASI': (20, 20, -120), 'RPSI': (-140, 40, 50), 'LPSI': (-140, 40, -50)}),
    ('torso', 'pelvis', 'lumbosacral',
     {'neck': (-40, 420, 0), 'r_shoulder': (-40, 380, 180), 'l_shoulder': (-40, 380, -180)},
     {'C7': (-80, 430, 0), 'T10': (-110, 200, 0), 'CLAV': (40, 390, 0), 'STRN': (80, 250, 0),
      'RBAK': (-110, 300, 90)}),
    ('head', 'torso', 'neck', {'head_top': (10, 230, 0)},
     {'RFHD': (90, 150, 60), 'LFHD': (90, 150, -60), 'RBHD': (-70, 140, 60), 'LBHD': (-70, 140, -60)}),
] + RIGHT + [_mirror(s) for s in RIGHT]

# coordinate -> (segment whose flexion it is, ROM min, max)
COORDINATES = {
    'pelvis_tilt': ('pelvis', None, None), 'lumbar_extension': ('torso', -80, 30),
    'neck_extension': ('head', -45, 45),
    'hip_flexion_r': ('r_thigh', -30, 120), 'knee_angle_r': ('r_shank', -140, 5),
    'ankle_angle_r': ('r_foot', -50, 30), 'arm_flex_r': ('r_upper_arm', -60, 180),
    'elbow_flex_r': ('r_forearm', -5, 150), 'wrist_flex_r': ('r_hand', -70, 80),
    'hip_flexion_l': ('l_thigh', -30, 120), 'knee_angle_l': ('l_shank', -140, 5),
    'ankle_angle_l': ('l_foot', -50, 30), 'arm_flex_l': ('l_upper_arm', -60, 180),
    'elbow_flex_l': ('l_forearm', -5, 150), 'wrist_flex_l': ('l_hand', -70, 80),
}
SENSORS = ['pelvis_imu', 'r_shank_imu']


def bones():
    """Per the design: each segment from its base joint to its children's
    base joints, or to its distal point when it has no child."""
    out = []
    for name, _, base, points, _ in SEGMENTS:
        children = [s[2] for s in SEGMENTS if s[1] == name]
        out += [[base, c] for c in (children or list(points))]
    return out


def model(up='y', config='stub (synthetic walk)'):
    joints = ['pelvis_origin'] + [j for s in SEGMENTS for j in s[3]]
    return {
        'config': config, 'units': 'mm',
        'lab_axes': {'up': [0, 0, 1] if up == 'z' else [0, 1, 0], 'forward': [1, 0, 0]},
        'joints': joints,
        'bones': bones(),
        'segments': [{'name': n, 'parent': p, 'origin': b} for n, p, b, _, _ in SEGMENTS],
        'markers': [{'name': m, 'segment': s[0]} for s in SEGMENTS for m in s[4]],
        'coordinates': [{'name': c, 'min_deg': lo, 'max_deg': hi} for c, (_, lo, hi) in COORDINATES.items()],
        'sensors': list(SENSORS),
    }


def occluded_at(frame):
    """The markers occluded in a frame: a fixed pattern the test checks the
    page against (gaps open and close every fraction of a second)."""
    out = []
    if (frame // 60) % 3 == 0:
        out.append('RKNE')
    if (frame // 45) % 4 == 1:
        out.append('LWRA')
    if (frame // 100) % 5 in (2, 3):
        out += ['RHEE', 'C7']
    return out


def _flexion(t):
    """Segment -> angle about its z axis relative to its parent (deg)."""
    ph = 2 * math.pi * 0.9 * t
    a = {'pelvis': 3 * math.sin(2 * ph), 'torso': -5 + 2 * math.sin(2 * ph), 'head': 5.0}
    for side, p in (('r', ph), ('l', ph + math.pi)):
        a[side + '_thigh'] = 10 + 20 * math.sin(p)
        a[side + '_shank'] = -35 + 30 * math.cos(p + 0.8)
        a[side + '_foot'] = 10 * math.sin(p - 1.0)
        a[side + '_upper_arm'] = -20 * math.sin(p)
        a[side + '_forearm'] = 20 + 10 * math.sin(p)
        a[side + '_hand'] = 0.0
    return a


def _rot_z(deg, v):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


def _to_lab(p, up):
    """Y-up positions into a Z-up lab (a turn of +90 deg about x)."""
    return [p[0], -p[2], p[1]] if up == 'z' else list(p)


def pose(frame, source_hz, up='y'):
    t = frame / source_hz
    rel = _flexion(t)
    root = (-2000 + (1200 * t) % 4000, 940 + 15 * math.cos(4 * math.pi * 0.9 * t), 0.0)
    world, base_pos, joints, markers, segments = {}, {'pelvis_origin': root}, {'pelvis_origin': root}, {}, {}
    for name, parent, base, points, mk in SEGMENTS:
        world[name] = rel[name] + (world[parent] if parent else 0.0)
        o = base_pos[base]
        place = lambda v: tuple(o[i] + r for i, r in enumerate(_rot_z(world[name], v)))  # noqa: E731
        for j, v in points.items():
            base_pos[j] = joints[j] = place(v)
        for m, v in mk.items():
            markers[m] = place(v)
        h = math.radians(world[name]) / 2
        q = [math.cos(h), 0.0, 0.0, math.sin(h)]
        if up == 'z':  # turn the frame into the Z-up lab too: qx(90) * q
            c = math.sqrt(0.5)
            q = [c * q[0] - c * q[1], c * q[0] + c * q[1], c * q[2] - c * q[3], c * q[3] + c * q[2]]
        segments[name] = {'q': [round(x, 7) for x in q], 'origin': [round(x, 3) for x in _to_lab(o, up)]}
    occ = occluded_at(frame)
    noise = lambda m, i: 2.5 * math.sin(frame * 0.37 + sum(map(ord, m)) * 1.3 + i * 2.1)  # noqa: E731
    measured = {m: [round(v + noise(m, i), 3) for i, v in enumerate(_to_lab(p, up))]
                for m, p in markers.items() if m not in occ}
    res = [math.dist(measured[m], _to_lab(markers[m], up)) for m in measured]
    rms = math.sqrt(sum(r * r for r in res) / len(res))
    worst = max(measured, key=lambda m: math.dist(measured[m], _to_lab(markers[m], up)))
    return {
        'frame': frame, 'time': round(t, 6), 'units': 'mm',
        'joints': {j: [round(x, 3) for x in _to_lab(p, up)] for j, p in joints.items()},
        'markers': {m: [round(x, 3) for x in _to_lab(p, up)] for m, p in markers.items()},
        'measured': measured,
        'occluded': occ,
        'held': [],
        'gap_s': {m: round(((frame % 60) + 1) / source_hz, 4) for m in occ},
        'residual': {'rms': round(rms, 4), 'max': round(max(res), 4), 'worst': worst,
                     'count': len(res), 'quality': 'good', 'beyond': []},
        'angles': {c: round(rel[seg], 4) for c, (seg, _, _) in COORDINATES.items()},
        'translations': {'pelvis_tx': round(root[0], 3), 'pelvis_ty': round(root[1], 3), 'pelvis_tz': 0.0},
        'segments': segments,
        'solver': {'status': 'converged', 'stop': 'converged', 'iterations': 3, 'solve_us': 25.0},
    }


# The modes whose poses rest on no measurement (untracked_pose), and the modes that send poses.
UNTRACKED_MODES = ('no-targets', 'held', 'outliers')
POSE_MODES = ('live',) + UNTRACKED_MODES
MODES = POSE_MODES + ('stall', 'silent', 'garbage', 'waiting')


def untracked_pose(frame, still_frame, source_hz, up='y', how='no-targets'):
    """A pose of `frame` that rests on no measurement (`how` one of
    UNTRACKED_MODES), its posture that of still_frame, as fabrikd keeps it."""
    p = pose(still_frame, source_hz, up)
    names = list(p['markers'])
    p['frame'], p['time'] = frame, round(frame / source_hz, 6)
    if how == 'outliers':
        p['outliers'] = sorted(p['measured'])
    else:
        gap = round(max(frame - still_frame, 1) / source_hz, 4)
        p.update(occluded=names, measured={}, gap_s={m: gap for m in names},
                 held=names if how == 'held' else [])
    p['residual'] = {'rms': 0.0, 'max': 0.0, 'worst': None, 'count': 0, 'quality': 'none', 'beyond': []}
    status = 'converged' if how == 'held' else 'no_targets'
    p['solver'] = {'status': status, 'stop': status, 'iterations': 0 if status == 'no_targets' else 2,
                   'solve_us': 4.0}
    return p


# --- The server. -------------------------------------------------------------

class Feed:
    """What every client is sent, switched by the commands on stdin."""

    def __init__(self, args):
        self.args = args
        self.mode = args.start_mode
        self.mode_since = time.monotonic()
        self.t0 = time.monotonic()
        self.still_frame = 1   # the posture the untracked modes keep
        self.lock = threading.Lock()
        self.clients = 0
        self.undecodable = 0
        self.model = model(args.up)
        self.relay = Relay(args.pose) if args.pose else None
        self.source = None   # None (no vendor source), 'down' or 'up'
        self.source_since = time.monotonic()
        self.source_connections = self.source_errors = 0

    def _errors_now(self):
        """A source that is down fails once a second (a refused attempt each)."""
        down_s = time.monotonic() - self.source_since if self.source == 'down' else 0.0
        return self.source_errors + (int(down_s) + 1 if self.source == 'down' else 0)

    def set_source(self, how):
        with self.lock:
            self.source_errors = self._errors_now()
            if how == 'up' and self.source != 'up':
                self.source_connections += 1
            self.source = None if how == 'none' else how
            self.source_since = time.monotonic()

    def source_stats(self, frames_in):
        """stats.source as fabrikd sends it (proto/stats.schema.json), or None."""
        with self.lock:
            if self.source is None:
                return None
            errors = self._errors_now()
            return {
                'url': SOURCE_URL, 'connected': self.source == 'up',
                'server': 'QTM RT protocol 1.19' if self.source_connections else None,
                'connections': self.source_connections,
                'reconnects': max(0, self.source_connections - 1),
                'errors': errors, 'bad_packets': 0,
                'frames': frames_in if self.source_connections else 0, 'frames_dropped': 0,
                'last_error': SOURCE_ERROR if errors else None}

    def set_mode(self, mode):
        with self.lock:
            if mode in UNTRACKED_MODES and self.mode not in UNTRACKED_MODES:
                self.still_frame = self.frame_now()
            self.mode, self.mode_since = mode, time.monotonic()

    def frame_now(self):
        return int((time.monotonic() - self.t0) * self.args.source_hz) + 1


class Relay:
    """Newest pose, stats and model from a fabrikd (ZeroMQ SUB)."""

    def __init__(self, endpoint):
        import zmq  # Debian's python3-zmq
        self.zmq = zmq
        self.lock = threading.Lock()
        self.pose = self.stats = self.model = None
        self.poses = 0        # poses received
        self.pose_at = None   # monotonic time of the last one
        self.undecodable = 0
        # `model` on a socket of its own: a fabrikd that does not publish it
        # drops the subscriber that asks (and it reconnects), not the poses.
        self.socks = []
        for topics in ((b'pose', b'stats'), (b'model',)):
            sub = zmq.Context.instance().socket(zmq.SUB)
            sub.setsockopt(zmq.LINGER, 0)
            for topic in topics:
                sub.setsockopt(zmq.SUBSCRIBE, topic)
            sub.connect(endpoint)
            self.socks.append(sub)
        threading.Thread(target=self.run, daemon=True).start()

    @staticmethod
    def decode(payload):
        if payload[:1] in (b'{', b'[', b' ', b'\n'):
            return json.loads(payload)
        import msgpack  # Debian's python3-msgpack
        return msgpack.unpackb(payload, raw=False)

    def run(self):
        poller = self.zmq.Poller()
        for sub in self.socks:
            poller.register(sub, self.zmq.POLLIN)
        while True:
            ready = dict(poller.poll())
            for sub in self.socks:
                if sub in ready:
                    self.take(sub.recv_multipart())

    def take(self, parts):
        try:
            topic, doc = parts[0].decode(), self.decode(parts[1])
        except Exception:  # noqa: BLE001 - whatever the payload is, it is garbage
            with self.lock:
                self.undecodable += 1
            return
        with self.lock:
            if topic == 'pose':
                self.pose, self.pose_at = doc, time.monotonic()
                self.poses += 1
                if self.model is None:
                    self.model = {'derived': True, 'config': 'fabrikd (model derived from a pose)',
                                  'units': doc.get('units', 'mm'),
                                  'lab_axes': {'up': [0, 1, 0], 'forward': [1, 0, 0]},
                                  'joints': list(doc['joints']), 'bones': [],
                                  'segments': [{'name': n, 'parent': None, 'origin': None}
                                               for n in doc.get('segments', {})],
                                  'markers': [{'name': m, 'segment': None} for m in doc['markers']],
                                  'coordinates': [{'name': c, 'min_deg': None, 'max_deg': None}
                                                  for c in doc.get('angles', {})],
                                  'sensors': []}
            elif topic == 'stats':
                self.stats = doc
            elif topic == 'model':
                self.model = doc

    def snapshot(self):
        with self.lock:
            return self.pose, self.poses, self.pose_at, self.stats, self.model, self.undecodable


class WebSocket:
    """One client: text frames out; what the client sends is read and dropped
    (a close is answered), bounded to MAX_CLIENT_MESSAGE bytes."""

    def __init__(self, sock):
        self.sock = sock
        self.closed = threading.Event()
        self.send_lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()

    def _recv(self, n):
        data = b''
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            if not chunk:
                raise ConnectionError('closed')
            data += chunk
        return data

    def _read(self):
        try:
            while True:
                b0, b1 = self._recv(2)
                n = b1 & 0x7F
                if n == 126:
                    n = struct.unpack('>H', self._recv(2))[0]
                elif n == 127:
                    n = struct.unpack('>Q', self._recv(8))[0]
                if n > MAX_CLIENT_MESSAGE:
                    break
                self._recv(4 + n if b1 & 0x80 else n)
                if b0 & 0x0F == 0x8:  # close
                    self._frame(0x8, b'')
                    break
        except (OSError, ConnectionError, ValueError):
            pass
        self.closed.set()

    def _frame(self, opcode, payload):
        n = len(payload)
        head = bytes([0x80 | opcode])
        head += bytes([n]) if n < 126 else (bytes([126]) + struct.pack('>H', n) if n < 65536
                                            else bytes([127]) + struct.pack('>Q', n))
        with self.send_lock:
            self.sock.sendall(head + payload)

    def send(self, text):
        try:
            self._frame(0x1, text.encode('utf-8'))
        except OSError:
            self.closed.set()


class Handler(http.server.BaseHTTPRequestHandler):
    server_version = 'stub_view_server'
    protocol_version = 'HTTP/1.1'

    def log_message(self, *a):  # quiet
        pass

    def file_for(self, path):
        if path in ('/', '/index.html'):
            return os.path.join(WEB_DIR, 'index.html')
        m = re.fullmatch(r'/app/([A-Za-z0-9_-]+)\.(js|css)', path)
        if m:
            return os.path.join(WEB_DIR, m.group(1) + '.' + m.group(2))
        if path in THREE_FILES:
            return os.path.join(THREE_DIR, THREE_FILES[path])
        return None

    def do_GET(self):
        if self.path == '/ws' and self.headers.get('Upgrade', '').lower() == 'websocket':
            return self.websocket()
        name = self.file_for(self.path)
        if name is None or not os.path.isfile(name):
            return self.reply(404, b'not found\n', 'text/plain')
        with open(name, 'rb') as f:
            self.reply(200, f.read(), TYPES.get(os.path.splitext(name)[1], 'application/octet-stream'))

    def do_POST(self):
        self.reply(405, b'GET only\n', 'text/plain')

    do_PUT = do_DELETE = do_HEAD = do_POST

    def reply(self, code, body, ctype):
        self.send_response(code)
        self.send_header('Content-Type', ctype)
        self.send_header('Content-Length', str(len(body)))
        self.send_header('Cache-Control', 'no-store')
        self.end_headers()
        self.wfile.write(body)

    def websocket(self):
        key = self.headers.get('Sec-WebSocket-Key', '')
        accept = base64.b64encode(hashlib.sha1((key + WS_GUID).encode()).digest()).decode()
        self.send_response(101)
        self.send_header('Upgrade', 'websocket')
        self.send_header('Connection', 'Upgrade')
        self.send_header('Sec-WebSocket-Accept', accept)
        self.end_headers()
        self.wfile.flush()
        self.close_connection = True
        feed = self.server.feed
        ws = WebSocket(self.connection)
        with feed.lock:
            full = feed.args.max_clients and feed.clients >= feed.args.max_clients
            if not full:
                feed.clients += 1
        if full:  # as fabrik view does: told why, then closed (the page retries)
            ws.send(json.dumps({'topic': 'status', 'data': {
                'stream': 'rejected', 'clients': feed.clients, 'max_clients': feed.args.max_clients,
                'message': 'too many viewers (max %d): close another page of this fabrik view (or start '
                           'it with a higher --max-clients); retrying' % feed.args.max_clients}}))
            ws._frame(0x8, struct.pack('>H', 1013))
            ws.closed.wait(2)
            return
        try:
            self.serve(ws, feed)
        finally:
            with feed.lock:
                feed.clients -= 1

    def serve(self, ws, feed):
        args = feed.args
        send = lambda topic, data: ws.send(json.dumps({'topic': topic, 'data': data}, separators=(',', ':')))  # noqa: E731
        if args.synthetic_trial:
            rate = 50.0
            poses = [pose(f, rate, args.up) for f in range(1, int(args.synthetic_trial * rate) + 1)]
            send('trial', {'model': feed.model, 'file': 'synthetic_walk.trc', 'poses': poses})
            ws.closed.wait()
            return
        if feed.relay:
            return self.serve_relay(ws, feed, send)
        send('model', feed.model)
        period = 1.0 / args.rate_hz
        next_send = time.monotonic()
        next_stats = next_send
        frames_in = 0
        while not ws.closed.is_set():
            now = time.monotonic()
            with feed.lock:
                mode, since, still = feed.mode, feed.mode_since, feed.still_frame
            if mode in POSE_MODES + ('garbage',):
                frames_in = feed.frame_now()
            if mode == 'live':
                send('pose', pose(feed.frame_now(), args.source_hz, args.up))
            elif mode in UNTRACKED_MODES:
                send('pose', untracked_pose(feed.frame_now(), still, args.source_hz, args.up, mode))
            elif mode == 'garbage':
                ws.send('{"topic": "pose", "data": not json')
                send('pose', {'frame': 'seven', 'joints': []})
                with feed.lock:
                    feed.undecodable += 1
            if mode == 'waiting' and now >= next_stats:
                next_stats += 1.0
                send('status', {'stream': 'waiting', 'message': 'waiting for poses from tcp://127.0.0.1:5556',
                                'poses_per_s': 0.0, 'undecodable': 0, 'clients': feed.clients})
            elif now >= next_stats and mode != 'silent':
                next_stats += 1.0
                stats = {
                    'uptime_s': round(now - feed.t0, 3), 'frames_in': frames_in, 'frames_out': frames_in,
                    'frames_dropped': 0, 'decode_errors': 0, 'unknown_markers': 0,
                    'solve_us': {'p50': 24.0, 'p99': 61.0, 'max': 80.0},
                    'queue_latency_us': {'p50': 120.0, 'p99': 300.0, 'max': 410.0},
                    'interval_s': 1.0, 'pose_rate_hz': args.source_hz if mode in POSE_MODES else 0.0,
                    'last_error': None, 'config': feed.model['config']}
                source = feed.source_stats(frames_in)
                if source is not None:
                    stats['source'] = source
                send('stats', stats)
                stream, message = 'ok', ''
                if mode == 'stall' and now - since >= 1.0:
                    stream, message = 'stalled', 'no pose from fabrikd for %.0f s' % (now - since)
                elif mode == 'garbage':
                    stream, message = 'garbage', 'undecodable poses on tcp://127.0.0.1:5556'
                send('status', {'stream': stream, 'message': message,
                                'poses_per_s': args.source_hz if mode in POSE_MODES else 0.0,
                                'undecodable': feed.undecodable, 'clients': feed.clients})
            next_send += period
            if next_send < now - period:  # far behind: newest wins, no burst
                next_send = now
            ws.closed.wait(max(0.0, next_send - time.monotonic()))


    def serve_relay(self, ws, feed, send):
        period = 1.0 / feed.args.rate_hz
        sent_model = sent_poses = last_stats = None
        next_send = next_status = time.monotonic()
        window = []  # (time, poses received) over the last second
        while not ws.closed.is_set():
            now = time.monotonic()
            pose_doc, poses, pose_at, stats, model_doc, undecodable = feed.relay.snapshot()
            if model_doc is not None and model_doc is not sent_model:
                send('model', model_doc)
                sent_model = model_doc
            if pose_doc is not None and poses != sent_poses and sent_model is not None:
                send('pose', pose_doc)
                sent_poses = poses
            if stats is not None and stats is not last_stats:
                send('stats', stats)
                last_stats = stats
            window = [w for w in window if w[0] > now - 1.0] + [(now, poses)]
            if now >= next_status:
                next_status += 1.0
                stream, message = 'ok', ''
                if pose_at is None:
                    stream, message = 'waiting', 'no pose from %s yet' % feed.args.pose
                elif now - pose_at > 1.0:
                    stream, message = 'stalled', 'no pose from %s for %.0f s' % (feed.args.pose, now - pose_at)
                send('status', {'stream': stream, 'message': message,
                                'poses_per_s': float(window[-1][1] - window[0][1]),
                                'undecodable': undecodable, 'clients': feed.clients})
            next_send += period
            if next_send < now - period:
                next_send = now
            ws.closed.wait(max(0.0, next_send - time.monotonic()))


class Server(http.server.ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('command', nargs='?', choices=['view'], help='ignored: `fabrik view`\'s command line')
    ap.add_argument('--listen', default='127.0.0.1:0')
    ap.add_argument('--pose', help='relay this fabrikd output endpoint instead of the synthetic walk')
    ap.add_argument('--rate-hz', type=float, default=60.0, help='poses per second sent to each client')
    ap.add_argument('--source-hz', type=float, default=250.0, help='the synthetic stream\'s frame rate')
    ap.add_argument('--up', choices=['y', 'z'], default='y')
    ap.add_argument('--start-mode', choices=MODES, default='live')
    ap.add_argument('--max-clients', type=int, default=0, help='0: no limit')
    ap.add_argument('--synthetic-trial', type=float, default=0.0, metavar='SECONDS')
    args = ap.parse_args()
    host, _, port = args.listen.rpartition(':')
    server = Server((host or '127.0.0.1', int(port)), Handler)
    server.feed = Feed(args)
    print('stub_view_server: http://%s:%d/' % server.server_address[:2], flush=True)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    for line in sys.stdin:
        cmd = line.strip()
        if cmd == 'quit':
            break
        if cmd in MODES:
            server.feed.set_mode(cmd)
            print('stub_view_server: mode %s' % cmd, flush=True)
        elif cmd in ('source-down', 'source-up', 'source-none'):
            server.feed.set_source(cmd.split('-')[1])
            print('stub_view_server: %s' % cmd, flush=True)
    else:
        # stdin closed (e.g. started from a shell in the background): serve on.
        threading.Event().wait()


if __name__ == '__main__':
    main()
