# Per-call cost of the Godot 3 binding from GDScript (run by bench/engines/run_bench.sh inside
# the Godot 3 test project): sample() alone, apply() (sample + one set_bone_pose per joint on a
# Skeleton), and the same loop calling an empty GDScript function, to show GDScript's own share.
extends SceneTree

func noop(_clip, _t, _flags):
	return 0

func best_of(rounds, n, what, anim, skeleton):
	var best = 1e30
	for r in range(rounds):
		var t0 = OS.get_ticks_usec()
		if what == "sample":
			for i in range(n):
				anim.sample(0, i / 60.0, 2)
		elif what == "apply":
			for i in range(n):
				anim.apply(skeleton, 0, i / 60.0, 2)
		else:
			for i in range(n):
				noop(0, i / 60.0, 2)
		best = min(best, float(OS.get_ticks_usec() - t0) / n)
	return best

func _init():
	var args = OS.get_cmdline_args()
	var path = "res://data/bench.mcd"
	var f = File.new()
	f.open(path, File.READ)
	var anim = load("res://addons/mocodec/mocodec_animation.gdns").new()
	if anim.load_bytes(f.get_buffer(f.get_len())) != 0:
		print("bench load failed")
		quit(1)
		return
	var skel_index = anim.get_clip_skeleton(0)
	var skeleton = Skeleton.new()
	get_root().add_child(skeleton)
	for i in range(anim.get_node_count(skel_index)):
		skeleton.add_bone(anim.get_node_name(skel_index, i))
		if anim.get_node_parent(skel_index, i) >= 0:
			skeleton.set_bone_parent(i, anim.get_node_parent(skel_index, i))
	anim.bind_skeleton(skeleton, skel_index)
	var n = 100000
	print("godot3_sample %d %.4f" % [anim.get_clip_node_count(0), best_of(5, n, "sample", anim, skeleton)])
	print("godot3_apply %d %.4f" % [anim.get_clip_node_count(0), best_of(5, n, "apply", anim, skeleton)])
	print("gdscript_empty_call %d %.4f" % [anim.get_clip_node_count(0), best_of(5, n, "noop", anim, skeleton)])
	quit(0)
