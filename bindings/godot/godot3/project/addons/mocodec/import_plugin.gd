# Imports a .mcd file as a MocodecAnimation resource (its bytes, checked by the runtime), saved
# as .res in .import/: a game then loads it with load("res://walk.mcd") and an exported game
# carries it like any other resource. A file the runtime refuses fails the import with one line.
tool
extends EditorImportPlugin

const MocodecAnimation = preload("res://addons/mocodec/mocodec_animation.gdns")


func get_importer_name():
	return "mocodec.mcd"


func get_visible_name():
	return "mocodec animation"


func get_recognized_extensions():
	return ["mcd"]


func get_save_extension():
	return "res"


func get_resource_type():
	return "Resource"


func get_preset_count():
	return 1


func get_preset_name(_preset):
	return "Default"


func get_import_options(_preset):
	return []


func get_option_visibility(_option, _options):
	return true


func get_priority():
	return 1.0


func get_import_order():
	return 0


func import(source_file, save_path, _options, _platform_variants, _gen_files):
	var f = File.new()
	if f.open(source_file, File.READ) != OK:
		printerr("%s: cannot be read" % source_file)
		return ERR_CANT_OPEN
	var bytes = f.get_buffer(f.get_len())
	f.close()
	var animation = MocodecAnimation.new()
	animation.data = bytes
	var result = animation.get_result()
	if result != 0:
		printerr("%s: not an asset this runtime reads: %s (mocodec result %d)" % [source_file, animation.result_string(result), result])
		return ERR_INVALID_DATA
	return ResourceSaver.save("%s.%s" % [save_path, get_save_extension()], animation)
