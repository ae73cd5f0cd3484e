"""`afe serve --ros2` seen as a ROS 2 node by a client that knows only rmw_zenoh's
protocol and the message definitions in ros/afe_msgs/: eclipse-zenoh for the wire,
rosbags for the type hashes and CDR (no afe code on the client side; the reference
frames come from `afe extract`)."""
import glob
import json
import os
import struct
import subprocess
import threading
import time
import wave

import numpy as np
import pytest

from conftest import free_port, zenoh_peer

zenoh = pytest.importorskip("zenoh")
typesys = pytest.importorskip("rosbags.typesys")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MSGS = os.path.join(ROOT, "ros", "afe_msgs")
PLATFORM = os.path.join(ROOT, "data", "platforms", "kemar-pan-unit.json")
NODE = "afe"
DOMAIN = 0
SERVICES = {"add_request": "AddRequest", "remove_request": "RemoveRequest",
            "modify_parameter": "ModifyParameter", "get_signals": "GetSignals",
            "get_parameters": "GetParameters"}


# ROS 2's own hash of service_msgs/msg/ServiceEventInfo, which every service's Event type
# refers to (the TYPE_VERSION_HASH of service_msgs' generated code, Jazzy).
SERVICE_EVENT_INFO = "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"


def typestore():
    """Jazzy's types plus afe_msgs, read from the package's own files; each service as
    rosidl expands it (Request, Response, Event and the service type)."""
    # rosidl reads a .msg `char` as uint8 (FieldType 3); rosbags 0.11 hashes it as
    # FieldType 13 and so misses ServiceEventInfo's hash (checked below)
    import rosbags.typesys.store
    rosbags.typesys.store.TIDMAP["char"] = rosbags.typesys.store.TIDMAP["uint8"]
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    assert store.hash_rihs01("service_msgs/msg/ServiceEventInfo") == SERVICE_EVENT_INFO
    types = {}
    for path in glob.glob(os.path.join(MSGS, "msg", "*.msg")):
        name = os.path.splitext(os.path.basename(path))[0]
        with open(path) as f:
            types.update(typesys.get_types_from_msg(f.read(), f"afe_msgs/msg/{name}"))
    for path in glob.glob(os.path.join(MSGS, "srv", "*.srv")):
        name = os.path.splitext(os.path.basename(path))[0]
        with open(path) as f:
            request, response = f.read().split("\n---\n")
        full = f"afe_msgs/srv/{name}"
        types.update(typesys.get_types_from_msg(request, f"{full}_Request"))
        types.update(typesys.get_types_from_msg(response, f"{full}_Response"))
        types.update(typesys.get_types_from_msg(
            f"service_msgs/ServiceEventInfo info\n{full}_Request[<=1] request\n"
            f"{full}_Response[<=1] response\n", f"{full}_Event"))
        types.update(typesys.get_types_from_msg(
            f"{full}_Request request_message\n{full}_Response response_message\n"
            f"{full}_Event event_message\n", full))
    # rosbags files a name outside msg/ under msg/ (afe_msgs/srv/msg/X): back to ROS's
    store.register({srv_name(k): srv_name(v) for k, v in types.items()})
    return store


def srv_name(value):
    """``value`` (a type name or a rosbags field definition) with afe_msgs/srv/msg/X
    names as afe_msgs/srv/X."""
    if isinstance(value, str):
        return value.replace("afe_msgs/srv/msg/", "afe_msgs/srv/")
    if isinstance(value, (tuple, list)):
        return type(value)(srv_name(v) for v in value)
    return value


def dds(full):
    *parts, last = full.split("/")
    return "::".join(parts) + f"::dds_::{last}_"


@pytest.fixture(scope="module")
def store():
    return typestore()


@pytest.fixture(scope="module")
def node(cli, tiled_wav):
    """`afe serve --ros2` on a free loopback port, and a Zenoh session connected to it.
    The server computes ratemap and ILD from its first block on (a robot's own
    requests): a ROS request for them shares their processors, so its frames are those of
    `afe extract` over the file, frame for frame."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    server = subprocess.Popen(
        [cli, "serve", "--source", f"wav:{tiled_wav}", "--listen", endpoint, "--block-ms", "10",
         "--for", "40", "--ros2", "--platform", PLATFORM, "-r", "ratemap,ild"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    session = zenoh_peer(endpoint)
    try:
        yield session, server
    finally:
        session.close()
        server.kill()
        server.wait()


def tokens(session):
    """The ROS 2 graph's liveliness tokens, as key expressions."""
    return [str(r.ok.key_expr) for r in session.liveliness().get(f"@ros2_lv/{DOMAIN}/**",
                                                                  timeout=2.0) if r.ok]


def entities(session, kind, deadline_s=15.0, want=1):
    """The tokens of ``kind`` (NN, MP, SS) of node afe, split into their chunks, waiting
    until at least ``want`` are there."""
    end = time.monotonic() + deadline_s
    while True:
        found = [t.split("/") for t in tokens(session)]
        found = [p for p in found if p[5] == kind and p[8] == NODE]
        if len(found) >= want or time.monotonic() > end:
            return found
        time.sleep(0.1)


def service_key(name, store):
    ty = f"afe_msgs/srv/{SERVICES[name]}"
    return f"{DOMAIN}/{NODE}/{name}/{dds(ty)}/{store.hash_rihs01(ty)}"


class Caller:
    """A ROS 2 service client in rmw_zenoh's way: a query with the request's CDR and an
    attachment (sequence number, time, GID)."""

    def __init__(self, session, store):
        self.session, self.store, self.seq = session, store, 0
        self.gid = os.urandom(16)

    def attachment(self):
        self.seq += 1
        return struct.pack("<qqB", self.seq, time.time_ns(), 16) + self.gid

    def raw(self, name, payload, attachment=True):
        replies = list(self.session.get(
            service_key(name, self.store), payload=payload,
            attachment=self.attachment() if attachment else None, timeout=10.0))
        assert len(replies) == 1, f"{name}: {len(replies)} replies"
        return replies[0]

    def __call__(self, name, **fields):
        ty = f"afe_msgs/srv/{SERVICES[name]}"
        msg = self.store.types[f"{ty}_Request"](**fields)
        reply = self.raw(name, bytes(self.store.serialize_cdr(msg, f"{ty}_Request")))
        assert reply.ok is not None, f"{name}: {reply.err.payload.to_string()}"
        seq, _, n = struct.unpack("<qqB", reply.ok.attachment.to_bytes()[:17])
        assert (seq, n) == (self.seq, 16), "the reply carries the call's sequence number"
        assert reply.ok.attachment.to_bytes()[17:] == self.gid, "and the caller's GID"
        return self.store.deserialize_cdr(reply.ok.payload.to_bytes(), f"{ty}_Response")


def parameter(store, name, value):
    return store.types["afe_msgs/msg/Parameter"](name=name, value=json.dumps(value))


def extract(cli, wav, tmp_path, requests):
    out = str(tmp_path / "ref.npz")
    subprocess.run([cli, "extract", wav, "-r", ",".join(requests), "-o", out], check=True,
                   stdout=subprocess.DEVNULL)
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def test_type_hashes_tokens_and_keys_are_rmw_zenohs(node, store):
    session, _ = node
    nodes = entities(session, "NN")
    assert len(nodes) == 1, nodes
    zid, node_id, entity_id = nodes[0][2:5]
    assert node_id == entity_id, "a node's token carries its own id twice"
    assert nodes[0][6:8] == ["%", "%"], "the default enclave and namespace, mangled"
    services = {p[9]: p for p in entities(session, "SS", want=len(SERVICES))}
    assert set(services) == {f"%{NODE}%{s}" for s in SERVICES}, services
    for name, ty in SERVICES.items():
        p = services[f"%{NODE}%{name}"]
        assert p[2] == zid
        full = f"afe_msgs/srv/{ty}"
        assert p[10] == dds(full)
        assert p[11] == store.hash_rihs01(full), f"{full}: the type hash is rosbags'"
        assert p[12] == "::,10:,:,:,,", "reliable, volatile, keep last 10"
    publishers = {p[9]: p for p in entities(session, "MP", want=2)}
    audio, platform = publishers[f"%{NODE}%audio"], publishers[f"%{NODE}%platform"]
    assert audio[10:12] == [dds("afe_msgs/msg/Audio"),
                            store.hash_rihs01("afe_msgs/msg/Audio")]
    assert platform[10:13] == [dds("std_msgs/msg/String"),
                               store.hash_rihs01("std_msgs/msg/String"), ":1:,1:,:,:,,"]


def test_the_platform_is_latched_and_the_audio_is_the_files(node, store, tiled_wav):
    session, _ = node
    entities(session, "MP", want=2)
    key = f"{DOMAIN}/{NODE}/platform/{dds('std_msgs/msg/String')}/" \
          f"{store.hash_rihs01('std_msgs/msg/String')}"
    # a late joiner asks the publisher's cache, as rmw_zenoh's transient-local
    # subscriptions (zenoh-ext's advanced subscribers) do
    replies = [r.ok for r in session.get(f"{key}/@adv/pub/**", timeout=5.0,
                                         accept_replies=zenoh.ReplyKeyExpr.ANY) if r.ok]
    assert [str(r.key_expr) for r in replies] == [key]
    assert replies, "the latched platform answers a late joiner"
    text = store.deserialize_cdr(replies[0].payload.to_bytes(), "std_msgs/msg/String").data
    with open(PLATFORM) as f:
        given, published = json.load(f), json.loads(text)
    # the descriptor as the server read it: the file's, with its defaults written out
    assert published["robot"] == given["robot"]
    assert [p["name"] for p in published["parts"]] == [p["name"] for p in given["parts"]]
    assert published["audio"]["sample_rate_hz"] == given["audio"]["sample_rate_hz"]
    assert [c["role"] for c in published["audio"]["channels"]] == ["left-ear", "right-ear"]
    akey = f"{DOMAIN}/{NODE}/audio/{dds('afe_msgs/msg/Audio')}/" \
           f"{store.hash_rihs01('afe_msgs/msg/Audio')}"
    got = []
    sub = session.declare_subscriber(akey, lambda s: got.append(s))
    end = time.monotonic() + 10
    while len(got) < 20 and time.monotonic() < end:
        time.sleep(0.05)
    sub.undeclare()
    assert len(got) >= 20
    with wave.open(tiled_wav) as w:
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2").reshape(-1, 2) / 32768.0
    for s in got:
        m = store.deserialize_cdr(s.payload.to_bytes(), "afe_msgs/msg/Audio")
        assert (m.sample_rate, m.channels, m.frames, m.frames_lost) == (44100.0, 2, 441, 0)
        start = m.first_frame % pcm.shape[0]
        assert np.array_equal(m.data.reshape(-1, 2), pcm[start:start + m.frames])
        assert m.header.stamp.sec > 1_600_000_000, "a Unix time stamp"


def test_services_place_requests_whose_topics_equal_afe_extract(node, store, cli, tiled_wav,
                                                                 tmp_path):
    session, server = node
    entities(session, "SS", want=len(SERVICES))
    call = Caller(session, store)
    added = call("add_request", request="ratemap", parameters=[])
    assert added.success, added.message
    ild = call("add_request", request="ild", parameters=[parameter(store, "ild_wSizeSec", 0.02)])
    assert ild.success, ild.message
    assert list(added.topics) == [f"/{NODE}/ratemap_left", f"/{NODE}/ratemap_right"]
    assert list(ild.topics) == [f"/{NODE}/ild_mono"]
    ty = "afe_msgs/msg/Signal"
    published = {p[9]: p for p in entities(session, "MP", want=5)}
    for topic in [*added.topics, *ild.topics]:
        p = published[topic.replace("/", "%")]
        assert p[10:13] == [dds(ty), store.hash_rihs01(ty), "::,10:,:,:,,"], "the topic appears"
    key = lambda topic: f"{DOMAIN}/{topic.strip('/')}/{dds(ty)}/{store.hash_rihs01(ty)}"
    got = {t: [] for t in [*added.topics, *ild.topics]}
    subs = [session.declare_subscriber(key(t), lambda s, t=t: got[t].append(s)) for t in got]
    end = time.monotonic() + 15
    while min(len(v) for v in got.values()) < 150 and time.monotonic() < end:
        time.sleep(0.05)
    for s in subs:
        s.undeclare()
    ref = extract(cli, tiled_wav, tmp_path, ["ratemap", "ild"])
    for topic, samples in got.items():
        assert len(samples) >= 150, f"{topic}: {len(samples)} messages"
        name = topic.rsplit("/", 1)[1]
        seqs = []
        compared = 0
        for s in samples:
            a = s.attachment.to_bytes()
            assert len(a) == 33 and a[16] == 16, "rmw_zenoh's attachment"
            seqs.append(struct.unpack("<q", a[:8])[0])
            m = store.deserialize_cdr(s.payload.to_bytes(), ty)
            assert (m.request, m.output) == (name.split("_")[0], name)
            assert m.sample_rate == 100.0
            assert list(m.frame_shape) == [m.centre_frequencies.size] == [ref[name].shape[1]]
            assert m.unit == ("dB" if name == "ild_mono" else "")
            rows = m.data.reshape(m.frames, -1)
            k = m.first_frame
            if m.frames and k + m.frames <= ref[name].shape[0]:
                assert np.array_equal(rows, ref[name][k:k + m.frames]), f"{name} at {k}"
                compared += m.frames
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), f"{topic}: none lost"
        assert compared >= 100, f"{topic}: {compared} frames compared"
    listed = call("get_signals")
    assert {s.topic for s in listed.signals} == set(got)
    assert {s.unit for s in listed.signals if s.request == "ild"} == {"dB"}

    params = call("get_parameters", request_id=ild.request_id)
    assert params.success
    assert json.loads({p.name: p.value for p in params.parameters}["ild_wSizeSec"]) == 0.02
    modified = call("modify_parameter", request_id=ild.request_id, parameter="ild_wSizeSec",
                    value="0.04")
    assert modified.success, modified.message
    params = call("get_parameters", request_id=ild.request_id)
    assert json.loads({p.name: p.value for p in params.parameters}["ild_wSizeSec"]) == 0.04

    removed = call("remove_request", request_id=ild.request_id)
    assert removed.success, removed.message
    end = time.monotonic() + 10
    while any(p[9] == f"%{NODE}%ild_mono" for p in entities(session, "MP")):
        assert time.monotonic() < end, "the removed request's topic goes"
        time.sleep(0.1)
    assert any(p[9] == f"%{NODE}%ratemap_left" for p in entities(session, "MP"))
    assert server.poll() is None


def test_bad_calls_get_clear_answers_and_disturb_nothing(node, store):
    session, server = node
    entities(session, "SS", want=len(SERVICES))
    call = Caller(session, store)
    unknown = call("add_request", request="ratemapp", parameters=[])
    assert not unknown.success and "ratemapp" in unknown.message, unknown.message
    bad = call("add_request", request="ratemap",
               parameters=[parameter(store, "fb_nChannelz", 16)])
    assert not bad.success and "fb_nChannelz" in bad.message, bad.message
    not_json = call("add_request", request="ratemap",
                    parameters=[store.types["afe_msgs/msg/Parameter"](name="fb_nChannels",
                                                                      value="sixteen")])
    assert not not_json.success and "JSON" in not_json.message
    gone = call("remove_request", request_id=999)
    assert not gone.success and "999" in gone.message
    wrong = call("modify_parameter", request_id=999, parameter="ild_wSizeSec", value="0.04")
    assert not wrong.success and "999" in wrong.message
    placed = call("add_request", request="ild", parameters=[])
    typo = call("modify_parameter", request_id=placed.request_id, parameter="ild_wSizeSecc",
                value="0.04")
    assert not typo.success and "ild_wSizeSecc" in typo.message, typo.message
    assert call("remove_request", request_id=placed.request_id).success

    malformed = call.raw("add_request", b"\x00\x01\x00\x00\xff\xff\xff\x7f")
    assert malformed.err is not None and "malformed" in malformed.err.payload.to_string()
    big_endian = call.raw("remove_request", b"\x00\x00\x00\x00" + bytes(8))
    assert big_endian.err is not None and "little-endian" in big_endian.err.payload.to_string()
    bare = call.raw("get_signals", b"\x00\x01\x00\x00\x00", attachment=False)
    assert bare.err is not None and "attachment" in bare.err.payload.to_string()

    # a flood: 300 calls from 6 threads at once; every one is answered as the service
    # answers (refused for its unknown id, or as busy), and the node goes on
    answers = []

    def flood():
        c = Caller(session, store)
        for _ in range(50):
            answers.append(c("remove_request", request_id=999))

    threads = [threading.Thread(target=flood) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(answers) == 300
    for a in answers:
        assert not a.success and ("999" in a.message or "try again" in a.message), a.message
    assert any("999" in a.message for a in answers)
    after = call("add_request", request="ic", parameters=[])
    assert after.success, after.message
    assert call("remove_request", request_id=after.request_id).success
    assert server.poll() is None
