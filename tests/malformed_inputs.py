"""Bad and odd input files built from the bundled samples: each variant is (name, file name,
bytes, expected) with expected ``"accept"`` (encoded within the tolerance) or ``"refuse"`` (one
line naming the file). Used by test_malformed_inputs.py; ``python tests/malformed_inputs.py DIR``
writes them out to try by hand."""
from __future__ import annotations

import base64
import json
import sys
from pathlib import Path

SAMPLES = Path(__file__).resolve().parents[1] / "encoder" / "mocodec" / "samples"


def _bvh_variants() -> list[tuple[str, str, bytes, str]]:
    text = (SAMPLES / "09_11.bvh").read_text()
    lines = text.split("\n")
    motion = lines.index("MOTION")
    first = motion + 3  # first frame line
    head, frames = lines[:motion], [ln for ln in lines[first:] if ln.strip()]

    def join(ls: list[str]) -> bytes:
        return ("\n".join(ls) + "\n").encode()

    def with_line(k: int, new: str) -> bytes:
        out = list(lines)
        out[k] = new
        return join(out)

    def with_frames(rows: list[str], count: int | None = None, time: str = ".0083333") -> bytes:
        return join(head + ["MOTION", f"Frames: {len(rows) if count is None else count}",
                            f"Frame Time: {time}"] + rows)

    offset_at = next(k for k, ln in enumerate(lines) if "OFFSET" in ln and k > 5)
    joint_at = next(k for k, ln in enumerate(lines) if ln.strip().startswith("JOINT"))
    chan_at = next(k for k, ln in enumerate(lines) if "CHANNELS 3" in ln)
    values = frames[0].split()
    odd = [
        ("CRLF line ends", text.replace("\n", "\r\n").encode(), "accept"),
        ("CR line ends", text.replace("\n", "\r").encode(), "accept"),
        ("UTF-8 BOM", b"\xef\xbb\xbf" + text.encode(), "accept"),
        ("tabs for spaces in frames", with_frames([r.replace(" ", "\t") for r in frames]), "accept"),
        ("blank lines between frames", with_frames([r + "\n" for r in frames]), "accept"),
        ("trailing spaces", join([ln + "   " for ln in lines]), "accept"),
        ("no final newline", text.rstrip("\n").encode(), "accept"),
        ("one frame", with_frames(frames[:1]), "accept"),
        ("two frames", with_frames(frames[:2]), "accept"),
        ("exponent notation", with_frames([" ".join(f"{float(v):e}" for v in r.split()) for r in frames]), "accept"),
        ("30 fps", with_frames(frames, time="0.0333333"), "accept"),
        ("1000 fps", with_frames(frames, time="0.001"), "accept"),
        ("frame values with + signs", with_frames(["+" + r.strip().replace(" -", " -").replace(" ", " +").replace("+-", "-")
                                                   for r in frames]), "accept"),
        ("rotation past 360 degrees", with_frames([" ".join(values[:3] + [str(float(v) + 720) for v in values[3:]])]
                                                  + frames[1:]), "accept"),
        ("joint named with spaces", with_line(joint_at, lines[joint_at].replace("LHipJoint", "L Hip Joint")), "accept"),
        ("joint named in Unicode", with_line(joint_at, lines[joint_at].replace("LHipJoint", "Hüfte_左")), "accept"),
        ("CHANNELS 0 on a joint", with_line(chan_at, lines[chan_at].split("CHANNELS")[0] + "CHANNELS 3 Xrotation Yrotation Zrotation"), "accept"),
    ]
    bad = [
        ("empty file", b"", "refuse"),
        ("only whitespace", b" \n\t\n", "refuse"),
        ("binary garbage", bytes(range(256)) * 64, "refuse"),
        ("not UTF-8", text.encode().replace(b"LHipJoint", b"L\xff\xfeHip"), "refuse"),
        ("UTF-16", text.encode("utf-16"), "refuse"),
        ("no MOTION", join(head), "refuse"),
        ("no HIERARCHY", join(lines[1:]), "refuse"),
        ("truncated in the hierarchy", join(lines[:joint_at + 4]), "refuse"),
        ("truncated in a frame", text[: len(text) - len(frames[-1]) // 2 - 1].encode(), "refuse"),
        ("Frames larger than the file", with_frames(frames, count=len(frames) + 5), "refuse"),
        ("Frames smaller than the file", with_frames(frames, count=len(frames) - 5), "refuse"),
        ("Frames 0", with_frames([], count=0), "refuse"),
        ("Frames negative", with_frames(frames, count=-3), "refuse"),
        ("Frames of 40 digits", with_frames(frames, count=10 ** 40), "refuse"),
        ("Frames 2^24 + 1", with_frames(frames, count=(1 << 24) + 1), "refuse"),
        ("Frame Time 0", with_frames(frames, time="0"), "refuse"),
        ("Frame Time negative", with_frames(frames, time="-0.01"), "refuse"),
        ("Frame Time 1e-7", with_frames(frames, time="1e-7"), "refuse"),
        ("Frame Time 1e-300", with_frames(frames, time="1e-300"), "refuse"),
        ("Frame Time 1e40", with_frames(frames, time="1e40"), "refuse"),
        ("Frame Time nan", with_frames(frames, time="nan"), "refuse"),
        ("Frame Time text", with_frames(frames, time="fast"), "refuse"),
        ("OFFSET 1e308", with_line(offset_at, "\t\tOFFSET 0 1e308 0"), "refuse"),
        ("OFFSET 2e7", with_line(offset_at, "\t\tOFFSET 0 2e7 0"), "refuse"),
        ("OFFSET nan", with_line(offset_at, "\t\tOFFSET nan 0 0"), "refuse"),
        ("OFFSET inf", with_line(offset_at, "\t\tOFFSET 0 0 -inf"), "refuse"),
        ("OFFSET of two numbers", with_line(offset_at, "\t\tOFFSET 0 1"), "refuse"),
        ("frame value 1e308", with_frames(["1e308 " + " ".join(values[1:])] + frames[1:]), "refuse"),
        ("frame value nan", with_frames([" ".join(values[:5] + ["nan"] + values[6:])] + frames[1:]), "refuse"),
        ("frame value text", with_frames([" ".join(values[:5] + ["abc"] + values[6:])] + frames[1:]), "refuse"),
        ("frame value 1_000", with_frames([" ".join(values[:5] + ["1_000"] + values[6:])] + frames[1:]), "refuse"),
        ("frame with a value missing", with_frames([" ".join(values[:-1])] + frames[1:]), "refuse"),
        ("frame with a value extra", with_frames([frames[0] + " 0"] + frames[1:]), "refuse"),
        ("unknown channel", with_line(chan_at, lines[chan_at].replace("Zrotation", "Wrotation", 1)), "refuse"),
        ("duplicate channel", with_line(chan_at, lines[chan_at].replace("Yrotation", "Zrotation", 1)), "refuse"),
        ("CHANNELS count wrong", with_line(chan_at, lines[chan_at].replace("CHANNELS 3", "CHANNELS 4")), "refuse"),
        ("CHANNELS count huge", with_line(chan_at, lines[chan_at].replace("CHANNELS 3", "CHANNELS 99999999999")), "refuse"),
        ("missing closing brace", join([ln for k, ln in enumerate(lines) if k != motion - 1]), "refuse"),
        ("extra closing brace", join(head + ["}", "MOTION"] + lines[motion + 1:]), "refuse"),
        ("JOINT without a name", with_line(joint_at, lines[joint_at].split("JOINT")[0] + "JOINT"), "refuse"),
        ("joint name with an escape", with_line(joint_at, lines[joint_at].replace("LHipJoint", "L\x1b[2JHip")), "refuse"),
        ("joint name of 300 bytes", with_line(joint_at, lines[joint_at].replace("LHipJoint", "J" * 300)), "refuse"),
        ("a megabyte line of garbage", join(lines[:4] + ["x" * (1 << 20)] + lines[4:]), "refuse"),
        ("1,100 joints", _wide_bvh(1100), "refuse"),
        ("deep nesting of 5,000 joints", _deep_bvh(5000), "refuse"),
        # Tiny files whose frame count no line backs: the motion arrays (frames x nodes) would
        # take gigabytes.
        ("no channels, Frames 3,000,000, no frame lines", _still_bvh(1, 3_000_000), "refuse"),
        ("200 channel-less joints, Frames 2^24", _still_bvh(200, 1 << 24), "refuse"),
        ("one channel, 1,000 joints, 20,000 frames", _wide_bvh(1000, frames=20_000, root_channels=1), "refuse"),
    ]
    return [(name, "v.bvh", data, expected) for name, data, expected in odd + bad]


def _wide_bvh(joints: int, frames: int = 1, root_channels: int = 3) -> bytes:
    names = " ".join(["Xposition", "Yposition", "Zposition"][:root_channels])
    ls = ["HIERARCHY", "ROOT Hips", "{", "\tOFFSET 0 0 0", f"\tCHANNELS {root_channels} {names}"]
    for i in range(joints):
        ls += [f"\tJOINT J{i}", "\t{", "\t\tOFFSET 1 0 0", "\t\tCHANNELS 0", "\t}"]
    rows = [" ".join(["0"] * root_channels)] * frames
    return ("\n".join(ls + ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.01"] + rows) + "\n").encode()


def _still_bvh(joints: int, frames: int) -> bytes:
    """A hierarchy without any channel that declares ``frames`` frames and holds no frame line."""
    ls = ["HIERARCHY", "ROOT Hips", "{", "\tOFFSET 0 0 0", "\tCHANNELS 0"]
    for i in range(joints):
        ls += [f"\tJOINT J{i}", "\t{", "\t\tOFFSET 1 0 0", "\t\tCHANNELS 0", "\t}"]
    return ("\n".join(ls + ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.01"]) + "\n").encode()


def _deep_bvh(depth: int) -> bytes:
    ls = ["HIERARCHY", "ROOT Hips", "{", "OFFSET 0 0 0", "CHANNELS 3 Xposition Yposition Zposition"]
    ls += [f"JOINT J{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0" for i in range(depth)] + ["}"] * (depth + 1)
    return ("\n".join(ls + ["MOTION", "Frames: 1", "Frame Time: 0.01", "0 0 0"]) + "\n").encode()


def _gltf_variants() -> list[tuple[str, str, bytes, str]]:
    doc = json.loads((SAMPLES / "gltf" / "SimpleSkin.gltf").read_text())

    def edited(change) -> bytes:
        d = json.loads(json.dumps(doc))
        change(d)
        return json.dumps(d).encode()

    def times_buffer(d, values) -> None:
        """Key times of the one animation replaced by ``values`` (float32) in a new buffer."""
        import struct
        raw = struct.pack(f"<{len(values)}f", *values)
        d["buffers"].append({"uri": "data:application/octet-stream;base64," + base64.b64encode(raw).decode(),
                             "byteLength": len(raw)})
        d["bufferViews"].append({"buffer": len(d["buffers"]) - 1, "byteLength": len(raw)})
        acc = d["accessors"][d["animations"][0]["samplers"][0]["input"]]
        acc.update(bufferView=len(d["bufferViews"]) - 1, byteOffset=0)
        acc.pop("min", None)
        acc.pop("max", None)

    sampler = lambda d: d["animations"][0]["samplers"][0]  # noqa: E731
    out_acc = lambda d: d["accessors"][sampler(d)["output"]]  # noqa: E731
    variants = [
        ("the sample as it is", json.dumps(doc).encode(), "accept"),
        ("STEP interpolation", edited(lambda d: sampler(d).update(interpolation="STEP")), "accept"),
        ("not JSON", b"{\"asset\": ", "refuse"),
        ("JSON but not an object", b"[1, 2, 3]", "refuse"),
        ("glTF version 1.0", edited(lambda d: d["asset"].update(version="1.0")), "refuse"),
        ("no animations", edited(lambda d: d.pop("animations")), "refuse"),
        ("no nodes", edited(lambda d: d.pop("nodes")), "refuse"),
        ("channel on a missing node", edited(lambda d: d["animations"][0]["channels"][0]["target"].update(node=99)), "refuse"),
        ("sampler index out of range", edited(lambda d: d["animations"][0]["channels"][0].update(sampler=7)), "refuse"),
        ("accessor index out of range", edited(lambda d: sampler(d).update(input=999)), "refuse"),
        ("accessor count past its buffer", edited(lambda d: out_acc(d).update(count=10 ** 9)), "refuse"),
        ("accessor count negative", edited(lambda d: out_acc(d).update(count=-1)), "refuse"),
        ("accessor of zeros (no bufferView) with count 10**9",
         edited(lambda d: (out_acc(d).pop("bufferView", None), out_acc(d).update(count=10 ** 9))), "refuse"),
        ("unknown interpolation", edited(lambda d: sampler(d).update(interpolation="BEZIER")), "refuse"),
        ("bad base64 buffer", edited(lambda d: d["buffers"][-1].update(uri="data:application/gltf-buffer;base64,@@@")), "refuse"),
        ("byteLength past the data", edited(lambda d: d["buffers"][-1].update(byteLength=10 ** 8)), "refuse"),
        ("buffer file missing", edited(lambda d: d["buffers"][-1].update(uri="missing.bin")), "refuse"),
        ("buffer file /dev/zero", edited(lambda d: d["buffers"][-1].update(uri="/dev/zero")), "refuse"),
        ("key times decreasing", edited(lambda d: times_buffer(d, [5.5 - 0.5 * i for i in range(12)])), "refuse"),
        ("key times nan", edited(lambda d: times_buffer(d, [float("nan")] * 12)), "refuse"),
        ("keys a million seconds apart", edited(lambda d: times_buffer(d, [i * 1e6 / 11 for i in range(12)])), "refuse"),
        # Within the frame limit (6 M frames at 24 Hz) but gigabytes once resampled.
        ("12 keys over 250,000 s", edited(lambda d: times_buffer(d, [i * 250_000 / 11 for i in range(12)])), "refuse"),
        ("node name with an escape (made _)", edited(lambda d: d["nodes"][2].update(name="bone\x1b[2J")), "accept"),
        ("cyclic node children", edited(lambda d: d["nodes"][2].update(children=[1])), "refuse"),
        ("compressed buffers required", edited(lambda d: d.update(extensionsRequired=["EXT_meshopt_compression"])), "refuse"),
    ]
    return [(name, "v.gltf", data, expected) for name, data, expected in variants]


def variants() -> list[tuple[str, str, bytes, str]]:
    """Every variant: (name, file name, bytes, "accept" or "refuse")."""
    return _bvh_variants() + _gltf_variants()


if __name__ == "__main__":
    folder = Path(sys.argv[1])
    folder.mkdir(parents=True, exist_ok=True)
    for i, (name, file, data, expected) in enumerate(variants()):
        (folder / f"{i:03d}_{expected}_{Path(file).stem}{Path(file).suffix}").write_bytes(data)
        print(f"{i:03d} {expected:6} {name}")
