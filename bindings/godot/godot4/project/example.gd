# Example (Godot 4, not run here): play a .mcd clip on a Skeleton3D whose bones are named like
# the BVH joints. Attach to a Node3D that has a Skeleton3D child called "Skeleton".
extends Node3D

@export_file("*.mcd") var asset_path := "res://walk.mcd"

func _ready() -> void:
	var animation := MocodecAnimation.new()
	animation.data = FileAccess.get_file_as_bytes(asset_path)
	if animation.get_result() != 0:
		push_error("not a valid mocodec asset: %d" % animation.get_result())
		return
	var player := MocodecSkeletonPlayer.new()
	player.animation = animation
	add_child(player)
	player.skeleton = player.get_path_to($Skeleton)
	player.clip = animation.find_clip(animation.get_clip_name(0))
