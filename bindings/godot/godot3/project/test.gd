# Headless test of the Godot 3 binding in the real engine:
#   godot3-server --no-window --path PROJECT -s test.gd
# Replays every asset in res://data against its reference poses (made by the Python binding of
# the same C runtime), checks bad bytes, poses Skeletons whose rests differ from the asset's
# through the runtime's retargeting, and loads the .mcd files the addon's importer turned into
# MocodecAnimation resources (run_tests.sh runs the editor once first). Prints "godot3: N passed, N failed"
# and quits with status 1 on any failure. A GDScript error would hang the engine instead of
# exiting, so the runner always wraps this in `timeout`.
extends SceneTree

const TOLERANCE = 1e-5
const WORLD = 1
const EXPECTED_VERSION_MAJOR_MINOR = 0x000300  # MCD_VERSION 0.3.x (0.3: mcd_sample takes a double time)
const SCRIPT_PATH = "res://addons/mocodec/mocodec_animation.gdns"

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


# Records of tests/golden/make_golden.py's format: {clip, time, flags, rows: [[qx..sz], ...]}
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
				var s = anim.get_pose_scale(i)
				if not check(e.size() == 10 and quat_close(q, e[0], e[1], e[2], e[3], TOLERANCE) and vec_close(t, e[4], e[5], e[6], TOLERANCE)
						and vec_close(s, e[7], e[8], e[9], TOLERANCE),
						"clip %d t=%f flags=%d node %d: got %s %s %s, want %s" % [r["clip"], r["time"], r["flags"], i, q, t, s, e]):
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


# World rest transforms of a skeleton's nodes (parents come first).
func node_world_rests(anim, skel_index):
	var world = []
	for i in range(anim.get_node_count(skel_index)):
		var rest = anim.get_node_rest(skel_index, i)
		var parent = anim.get_node_parent(skel_index, i)
		world.append(rest if parent < 0 else world[parent] * rest)
	return world


# A rig for the asset's skeleton built as a game rig would be: its own rest rotation on every
# bone (a random turn of the node's), bone names of its own, lengths `scale` times the
# asset's, the Skeleton's origin in metres; names in capitals (Godot forbids ':' in bone names,
# so no namespace), which the runtime's loose name match pairs with the asset's. Retargeted by the runtime, every joint must land
# where the asset's world-space sample has it, scaled.
func make_rig(anim, skel_index, scale, seed_value):
	var rng = RandomNumberGenerator.new()
	rng.seed = seed_value
	var skeleton = Skeleton.new()
	get_root().add_child(skeleton)
	var world = node_world_rests(anim, skel_index)
	var rig_world = []
	for i in range(world.size()):
		var turn = Basis(Vector3(rng.randf() - 0.5, 1.0, rng.randf()).normalized(), rng.randf_range(0.3, 2.8))
		rig_world.append(Transform(world[i].basis.orthonormalized() * turn, world[i].origin * scale))
		skeleton.add_bone(anim.get_node_name(skel_index, i).to_upper())
		var parent = anim.get_node_parent(skel_index, i)
		if parent >= 0:
			skeleton.set_bone_parent(i, parent)
			skeleton.set_bone_rest(i, rig_world[parent].affine_inverse() * rig_world[i])
		else:
			skeleton.set_bone_rest(i, rig_world[i])
	return skeleton


func test_retargeted_skeleton(anim, name):
	begin(name + ": a Skeleton with its own rests, retargeted")
	anim.load_bytes(read_bytes("res://data/" + name + ".mcd"))
	for c in range(anim.get_clip_count()):
		var skel_index = anim.get_clip_skeleton(c)
		var count = anim.get_node_count(skel_index)
		var metres = anim.get_cm_per_unit(skel_index) / 100.0
		for scale in [metres, 0.5 * metres]:
			var skeleton = make_rig(anim, skel_index, scale, 17 + c)
			var virtual = 0
			for i in range(count):
				if anim.get_node_kind(skel_index, i) == 2:
					virtual += 1
			check(anim.bind_skeleton(skeleton, skel_index, scale) == count - virtual, "every joint and end site matched by name")
			for i in range(count):
				check(anim.get_bone_node(i) == (-1 if anim.get_node_kind(skel_index, i) == 2 else i), "bone %d -> node" % i)
			var duration = anim.get_clip_duration(c)
			for k in range(7):
				var t = duration * k / 6.0
				check(anim.apply(skeleton, c, t, 0) == 0, "apply")
				check(anim.sample(c, t, WORLD) == 0, "world sample")
				# Godot composes in float32 down chains of ~8 bones
				var tol = 2e-4 * max(1.0, (anim.get_pose_translation(0) * scale).length())
				for i in range(count):
					var g = skeleton.get_bone_global_pose(i)
					var p = anim.get_pose_translation(i) * scale
					if not check(g.origin.distance_to(p) <= tol,
							"clip %d scale %f t=%f bone %d: at %s, the world sample at %s" % [c, scale, t, i, g.origin, p]):
						break
			check(anim.apply(skeleton, c, 0.0, WORLD) != 0, "world flag refused by apply")
			skeleton.free()
	finish()


# An A-posed rig: every limb swung 40 degrees at its first joint. With bone directions matched
# (flag 2, the default), each bone with one child points where the asset's bone points.
func test_a_posed_rig(anim, name):
	begin(name + ": an A-posed rig follows the asset's bone directions")
	anim.load_bytes(read_bytes("res://data/" + name + ".mcd"))
	var skel_index = anim.get_clip_skeleton(0)
	var count = anim.get_node_count(skel_index)
	var skeleton = make_rig(anim, skel_index, 1.0, 5)
	var children = []
	for i in range(count):
		children.append([])
	for i in range(count):
		var parent = anim.get_node_parent(skel_index, i)
		if parent >= 0 and anim.get_node_kind(skel_index, i) != 2:
			children[parent].append(i)
	var swung = 0
	for i in range(1, count):
		var parent = anim.get_node_parent(skel_index, i)
		if parent >= 0 and children[parent].size() >= 2 and children[i].size() == 1:
			var rest = skeleton.get_bone_rest(i)
			var d = rest.basis.xform(skeleton.get_bone_rest(children[i][0]).origin)
			var axis = d.cross(Vector3.UP)
			if axis.length() > 1e-6 * (1.0 + d.length()):
				skeleton.set_bone_rest(i, Transform(Basis(axis.normalized(), 0.7) * rest.basis, rest.origin))
				swung += 1
	check(swung > 0, "limbs to swing")
	for flags in [3, 1]:
		check(anim.bind_skeleton(skeleton, skel_index, 1.0, flags) > 0, "bind")
		var worst = 0.0
		for k in range(5):
			var t = anim.get_clip_duration(0) * k / 4.0
			anim.apply(skeleton, 0, t, 0)
			anim.sample(0, t, WORLD)
			for i in range(count):
				if children[i].size() != 1:
					continue
				var c = children[i][0]
				var u = skeleton.get_bone_global_pose(c).origin - skeleton.get_bone_global_pose(i).origin
				var v = anim.get_pose_translation(c) - anim.get_pose_translation(i)
				if u.length() > 1e-6 and v.length() > 1e-6:
					worst = max(worst, u.angle_to(v))
		if flags == 3:
			check(worst <= 1e-3, "bone directions off by %f rad with directions matched" % worst)
		else:
			check(worst > 0.3, "without matching, the swung limbs are only %f rad off" % worst)
	skeleton.free()
	finish()


# The importer of addons/mocodec ran in the editor (run_tests.sh): each .mcd of res://data loads
# as a MocodecAnimation resource with the file's bytes; the broken one did not import.
func test_imported(anim, name):
	begin(name + ": imported by the addon")
	var res = load("res://data/" + name + ".mcd")
	if check(res != null, "load(res://data/%s.mcd) gave null: not imported" % name):
		check(res.get_result() == 0, "imported resource opens")
		check(res.data == read_bytes("res://data/" + name + ".mcd"), "the resource holds the file's bytes")
		anim.load_bytes(read_bytes("res://data/" + name + ".mcd"))
		check(res.get_clip_count() == anim.get_clip_count() and res.get_clip_name(0) == anim.get_clip_name(0), "same clips")
	finish()


func test_resource_round_trip(anim, golden):
	begin("MocodecAnimation saves and loads as a resource")
	anim.data = read_bytes("res://data/" + golden + ".mcd")
	check(anim.get_result() == 0, "data property opens the bytes")
	check(ResourceSaver.save("user://round_trip.res", anim) == OK, "ResourceSaver.save")
	var back = ResourceLoader.load("user://round_trip.res", "", true)
	if check(back != null, "load"):
		check(back.get_result() == 0 and back.get_clip_count() == anim.get_clip_count(), "the loaded resource opens")
		check(back.sample(0, 0.3, 0) == 0 and anim.sample(0, 0.3, 0) == 0, "both sample")
		check(back.get_pose_translation(0) == anim.get_pose_translation(0), "same pose")
	var broken = load("res://data/broken.mcd")
	check(broken == null, "a corrupt .mcd is not imported")
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
	b[8] = 3
	check(anim.load_bytes(b) == 4, "major 3 -> VERSION_TOO_NEW")
	b[8] = 1
	check(anim.load_bytes(b) == 5, "major 1 -> VERSION_TOO_OLD")
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
	var script = load(SCRIPT_PATH)
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
		test_retargeted_skeleton(anim, name)
		test_imported(anim, name)
	if golden != "":
		test_bad_bytes(anim, golden)
		test_a_posed_rig(anim, golden)
		test_resource_round_trip(anim, golden)
	else:
		begin("golden asset present")
		check(false, "no golden_*.mcd in res://data")
		finish()
	print("godot3 tests ran in Godot ", Engine.get_version_info()["string"], " (headless)")
	print("godot3: %d passed, %d failed" % [passed, failed])
	return 1 if failed > 0 else 0


func _init():
	quit(run())
