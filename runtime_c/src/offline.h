/* Encoder support (not installed): what the Python encoder asks the runtime while it writes an
 * asset, through the cffi binding, so the numbers it stores are the runtime's own. */
#ifndef MCD_OFFLINE_H
#define MCD_OFFLINE_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

/* The codec scratch bytes (a multiple of 16) a clip of codec `codec` needs, for its clip
 * record: its payload is section[payload_offset .. + payload_size) of a complete codec
 * section of the version the encoder writes now (RMAL 4 for rma), its skeleton a complete
 * SKEL section. Checks the payload as mcd_validate would
 * (MCD_ERROR_MALFORMED, MCD_ERROR_UNSUPPORTED for an unknown codec). */
mcd_result mcd_offline_clip_scratch(uint32_t codec, const uint8_t* section, size_t section_size,
                                    size_t payload_offset, size_t payload_size, const uint8_t* skeleton,
                                    size_t skeleton_size, uint32_t frame_count, float frame_rate,
                                    size_t* out_size);

#endif /* MCD_OFFLINE_H */
