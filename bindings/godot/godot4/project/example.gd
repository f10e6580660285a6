# Example (Godot 4.3+, not run here): with addons/mocodec enabled, a .mcd in the project imports
# as a MocodecAnimation. A MocodecSkeletonModifier, a child of the Skeleton3D, plays one clip on
# it in the skeleton's modification pass (after any AnimationPlayer / AnimationTree; blend with
# its `influence`), retargeted onto the skeleton's own bone names, rests and proportions.
extends Node3D

@export var animation: MocodecAnimation = preload("res://walk.mcd")


func _ready() -> void:
	if animation.get_result() != 0:
		push_error("not a valid mocodec asset: %d" % animation.get_result())
		return
	var modifier := MocodecSkeletonModifier.new()
	modifier.animation = animation
	modifier.clip = animation.find_clip(animation.get_clip_name(0))
	modifier.root_motion = false  # stay in place; the hips still move up and down
	$Skeleton3D.add_child(modifier)
