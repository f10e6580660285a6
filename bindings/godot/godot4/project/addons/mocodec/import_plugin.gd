# Imports a .mcd file as a MocodecAnimation resource (the bytes, checked by the runtime), saved
# as .res under .godot/imported: a game loads it with load("res://walk.mcd") and an exported
# game carries it like any resource. A file the runtime refuses fails the import with one line.
@tool
extends EditorImportPlugin


func _get_importer_name() -> String:
	return "mocodec.mcd"


func _get_visible_name() -> String:
	return "mocodec animation"


func _get_recognized_extensions() -> PackedStringArray:
	return PackedStringArray(["mcd"])


func _get_save_extension() -> String:
	return "res"


func _get_resource_type() -> String:
	return "MocodecAnimation"


func _get_preset_count() -> int:
	return 1


func _get_preset_name(_preset_index: int) -> String:
	return "Default"


func _get_import_options(_path: String, _preset_index: int) -> Array[Dictionary]:
	return []


func _get_option_visibility(_path: String, _option_name: StringName, _options: Dictionary) -> bool:
	return true


func _get_priority() -> float:
	return 1.0


func _get_import_order() -> int:
	return 0


func _import(source_file: String, save_path: String, _options: Dictionary, _platform_variants: Array[String],
		_gen_files: Array[String]) -> Error:
	var bytes := FileAccess.get_file_as_bytes(source_file)
	if bytes.is_empty() and FileAccess.get_open_error() != OK:
		push_error("%s: cannot be read" % source_file)
		return FileAccess.get_open_error()
	var animation := MocodecAnimation.new()
	animation.data = bytes
	if animation.get_result() != 0:
		push_error("%s: not an asset this runtime reads (mocodec result %d)" % [source_file, animation.get_result()])
		return ERR_INVALID_DATA
	return ResourceSaver.save(animation, "%s.%s" % [save_path, _get_save_extension()])
