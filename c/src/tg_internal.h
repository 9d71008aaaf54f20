/* Shared by the library's sources; not part of the API (include/topgimbal.h is). */
#ifndef TG_INTERNAL_H
#define TG_INTERNAL_H

#include "topgimbal.h"

/* Hex digit values ('0'-'9', 'A'-'F', 'a'-'f'), -1 for any other byte (defined in tg_codec.c). */
extern const int8_t tg_hexval[256];

#endif
