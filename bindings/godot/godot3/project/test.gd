# Headless test of the Godot 3 binding in the real engine:
#   godot3-server --no-window --path PROJECT -s test.gd
# Replays every asset in res://data against its reference poses (made by the Python binding of
# the same C runtime), checks bad bytes, and drives a Skeleton. Prints "godot3: N passed, N failed"
# and quits with status 1 on any failure. A GDScript error would hang the engine instead of
# exiting, so the runner always wraps this in `timeout`.
extends SceneTree

const TOLERANCE = 1e-5
const WORLD = 1
const EXPECTED_VERSION_MAJOR_MINOR = 0x000100  # MCD_VERSION 0.1.x

var passed = 0
var failed = 0
var case_ok = true
var case_name = ""


func begin(name):
	case_name = name
	case_ok = true


func check(condition, what):
	if not condition and case_ok:
		printerr("FAIL ", case_name, ": ", what)
	if not condition:
		case_ok = false
	return condition


func finish():
	if case_ok:
		passed += 1
	else:
		failed += 1


func read_bytes(path):
	var f = File.new()
	if f.open(path, File.READ) != OK:
		return null
	var b = f.get_buffer(f.get_len())
	f.close()
	return b


# Records of tests/golden/make_golden.py's format: {clip, time, flags, rows: [[qx..tz], ...]}
func read_poses(path):
	var f = File.new()
	f.open(path, File.READ)
	var lines = f.get_as_text().split("\n", false)
	f.close()
	var records = []
	var current = null
	for line in lines:
		var parts = line.split(" ", false)
		if parts[0] == "sample":
			current = {"clip": int(parts[1]), "time": float(parts[2]), "flags": int(parts[3]), "rows": []}
			records.append(current)
		else:
			var row = []
			for p in parts:
				row.append(float(p))
			current["rows"].append(row)
	return records


func asset_names():
	var names = []
	var dir = Directory.new()
	if dir.open("res://data") != OK:
		return names
	dir.list_dir_begin(true, true)
	var f = dir.get_next()
	while f != "":
		if f.ends_with(".mcd") and dir.file_exists(f.get_basename() + ".poses.txt"):
			names.append(f.get_basename())
		f = dir.get_next()
	names.sort()
	return names


func quat_close(q, x, y, z, w, tol):
	return abs(q.x - x) <= tol and abs(q.y - y) <= tol and abs(q.z - z) <= tol and abs(q.w - w) <= tol


func vec_close(v, x, y, z, tol):
	return abs(v.x - x) <= tol and abs(v.y - y) <= tol and abs(v.z - z) <= tol


func test_reference_poses(anim, name):
	begin(name + ": reference poses")
	var bytes = read_bytes("res://data/" + name + ".mcd")
	if check(anim.load_bytes(bytes) == 0, "load_bytes"):
		var records = read_poses("res://data/" + name + ".poses.txt")
		check(records.size() > 0, "reference records")
		for r in records:
			if not case_ok:
				break
			check(anim.get_clip_node_count(r["clip"]) == r["rows"].size(), "node count")
			check(anim.sample(r["clip"], r["time"], r["flags"]) == 0, "sample")
			for i in range(r["rows"].size()):
				var e = r["rows"][i]
				var q = anim.get_pose_rotation(i)
				var t = anim.get_pose_translation(i)
				if not check(quat_close(q, e[0], e[1], e[2], e[3], TOLERANCE) and vec_close(t, e[4], e[5], e[6], TOLERANCE),
						"clip %d t=%f flags=%d node %d: got %s %s, want %s" % [r["clip"], r["time"], r["flags"], i, q, t, e]):
					break
	finish()


func test_queries(anim, name):
	begin(name + ": queries")
	anim.load_bytes(read_bytes("res://data/" + name + ".mcd"))
	check(anim.get_clip_count() >= 1, "clip count")
	for c in range(anim.get_clip_count()):
		var clip_name = anim.get_clip_name(c)
		check(anim.find_clip(clip_name) == c, "find_clip(%s)" % clip_name)
		var frames = anim.get_clip_frame_count(c)
		check(abs(anim.get_clip_duration(c) - (frames - 1) / anim.get_clip_frame_rate(c)) < 1e-3, "duration")
		var skel = anim.get_clip_skeleton(c)
		check(anim.get_node_count(skel) == anim.get_clip_node_count(c), "node count")
		check(anim.get_node_parent(skel, 0) == -1, "root first")
		check(anim.get_cm_per_unit(skel) > 0.0, "cm per unit")
	check(anim.find_clip("no such clip") == -1, "unknown clip name")
	finish()


# A Skeleton built from the asset's joints, with rests that are not identity (rest offset plus
# a twist), driven by apply(): each bone's global pose must equal the runtime's world sample.
func test_skeleton(anim, name):
	begin(name + ": skeleton bone poses")
	anim.load_bytes(read_bytes("res://data/" + name + ".mcd"))
	for c in range(anim.get_clip_count()):
		var skel_index = anim.get_clip_skeleton(c)
		var skeleton = Skeleton.new()
		get_root().add_child(skeleton)
		var count = anim.get_node_count(skel_index)
		for i in range(count):
			skeleton.add_bone(anim.get_node_name(skel_index, i))
			var parent = anim.get_node_parent(skel_index, i)
			if parent >= 0:
				skeleton.set_bone_parent(i, parent)
			var twist = Basis(Vector3(0.3, 1.0, -0.2).normalized(), 0.05 * i)
			skeleton.set_bone_rest(i, Transform(twist, anim.get_node_rest_offset(skel_index, i)))
		check(anim.bind_skeleton(skeleton, skel_index) == count, "every joint matched by name")
		var duration = anim.get_clip_duration(c)
		for k in range(7):
			var t = duration * k / 6.0
			check(anim.apply(skeleton, c, t, 0) == 0, "apply")
			check(anim.sample(c, t, WORLD) == 0, "world sample")
			# Godot composes in float32 down chains of ~8 bones: allow a little more than the
			# direct comparison, relative to the skeleton's size in its units.
			var tol = 2e-4 * max(1.0, anim.get_pose_translation(0).length())
			for i in range(count):
				var g = skeleton.get_bone_global_pose(i)
				var q = anim.get_pose_rotation(i)
				var p = anim.get_pose_translation(i)
				var gq = g.basis.get_rotation_quat()
				if not check(abs(gq.dot(q)) >= 1.0 - 1e-5 and g.origin.distance_to(p) <= tol,
						"clip %d t=%f bone %d: global %s %s, world sample %s %s" % [c, t, i, gq, g.origin, q, p]):
					break
		check(anim.apply(skeleton, c, 0.0, WORLD) != 0, "world flag refused by apply")
		skeleton.free()
	finish()


func test_bad_bytes(anim, golden):
	begin("bad bytes give the runtime's codes")
	var original = read_bytes("res://data/" + golden + ".mcd")
	check(anim.load_bytes(PoolByteArray()) == 2, "empty -> TRUNCATED")
	check(anim.get_clip_count() == 0, "a failed load leaves no asset")
	var b = PoolByteArray(original)
	b[1] = b[1] ^ 0x20
	check(anim.load_bytes(b) == 3, "magic -> BAD_MAGIC")
	b = PoolByteArray(original)
	b[8] = 2
	check(anim.load_bytes(b) == 4, "major 2 -> VERSION_TOO_NEW")
	b = PoolByteArray(original)
	b[b.size() / 2] = b[b.size() / 2] ^ 0x10
	check(anim.load_bytes(b) == 6, "flipped bit -> CHECKSUM")
	b = PoolByteArray(original)
	b.resize(b.size() - 16)
	check(anim.load_bytes(b) == 2, "truncated -> TRUNCATED")
	b = PoolByteArray(original)
	b.append_array(PoolByteArray([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]))
	check(anim.load_bytes(b) == 12, "trailing -> TRAILING_DATA")
	check(anim.load_bytes(original) == 0, "the original loads")
	check(anim.sample(anim.get_clip_count(), 0.0, 0) == 10, "clip index -> OUT_OF_RANGE")
	check(anim.sample(0, NAN, 0) == 1, "NaN time -> INVALID_ARGUMENT")
	check(anim.result_string(6) != "", "result_string")
	finish()


func run():
	var script = load("res://mocodec_animation.gdns")
	if script == null:
		printerr("FAIL: cannot load the NativeScript")
		return 1
	var anim = script.new()
	begin("native library version")
	check((anim.get_version() & 0xFFFF00) == EXPECTED_VERSION_MAJOR_MINOR, "mcd_version %x" % anim.get_version())
	finish()
	var names = asset_names()
	begin("test data present")
	check(names.size() >= 2, "assets in res://data: %s" % [names])
	finish()
	var golden = ""
	for name in names:
		if name.begins_with("golden_") and golden == "":
			golden = name
		test_reference_poses(anim, name)
		test_queries(anim, name)
		test_skeleton(anim, name)
	if golden != "":
		test_bad_bytes(anim, golden)
	else:
		begin("golden asset present")
		check(false, "no golden_*.mcd in res://data")
		finish()
	print("godot3 tests ran in Godot ", Engine.get_version_info()["string"], " (headless)")
	print("godot3: %d passed, %d failed" % [passed, failed])
	return 1 if failed > 0 else 0


func _init():
	quit(run())
