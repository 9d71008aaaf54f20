/*
 * libtopgimbal: the TOP gimbal-camera protocol (TOPOTEK SIP, SkyDroid C10..C20) in C99.
 *
 * No heap, no mutable globals, nothing from libc beyond <stdint.h>, <stddef.h>, <string.h>.
 * The command tables are generated from the Python catalog (python -m topgimbal.tools.cgen);
 * see docs/c.md for the API tour and porting notes.
 *
 * Values are fixed point: a number is `mantissa * 10^exp10` (tg_value.num, tg_value.exp10),
 * in the field's user unit (degrees, deg/s, metres, ...).
 *
 * Preconditions (not checked: breaking one is undefined behaviour, as for memcpy):
 *  - pointer arguments are not NULL, except where a comment allows it: an input of n bytes may be
 *    NULL when n is 0, an output buffer may be NULL when its capacity is 0;
 *  - an input pointer points to as many bytes as its length says, an output buffer to `cap` bytes;
 *  - tables (dialects, commands, forms, codecs) are the generated ones, a form belongs to the
 *    command it is used with, and value arrays have one entry per field of the form;
 *  - a tg_parser is set up by tg_parser_init before any other call, and one is used by one
 *    thread at a time (no function keeps state elsewhere: different objects are independent).
 * Everything else (values of any type or range, enum indices, header codes, addresses, controls,
 * identifiers, lengths, capacities) is checked and answered with a tg_status. On an error an
 * output buffer may hold partial bytes: only a non-negative return says what was written.
 */
#ifndef TOPGIMBAL_H
#define TOPGIMBAL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "tg_limits.h" /* generated: TG_CATALOG_MAX_DATA, TG_CATALOG_MAX_FIELDS */

#ifdef __cplusplus
extern "C" {
#endif

/* ---- limits ------------------------------------------------------------------------------- */

/* Largest data length the streaming parser accepts (default: the catalog's longest form). */
#ifndef TG_PARSER_MAX_DATA
#define TG_PARSER_MAX_DATA TG_CATALOG_MAX_DATA
#endif
/* A frame is 12 bytes of envelope plus its data. */
#define TG_FRAME_MAX (12 + TG_PARSER_MAX_DATA)
/* The parser holds one candidate frame plus one that may start inside it and run past it. */
#define TG_PARSER_BUF (2 * TG_FRAME_MAX)

/* ---- results ------------------------------------------------------------------------------ */

enum tg_status {
    TG_OK = 0,
    TG_E_INVALID = -1,   /* the bytes do not fit (the Python codec rejects them too) */
    TG_E_UNSURE = -2,    /* a spelling outside the strict subset the C core decodes */
    TG_E_RANGE = -3,     /* a value outside what the field allows */
    TG_E_TYPE = -4,      /* a value of the wrong type for the field */
    TG_E_SPACE = -5,     /* the output buffer is too small */
    TG_E_UNKNOWN = -6,   /* identifier not in the dialect */
    TG_E_NO_FORM = -7,   /* no form of the command fits the data */
    TG_E_ARG = -8        /* bad argument (address, control, header, missing field) */
};

/* A status in words ("value out of range (TG_E_RANGE)"), for log lines; any int is accepted. */
const char *tg_status_text(int status);

/* ---- frames ------------------------------------------------------------------------------- */

enum tg_header { TG_HDR_NONE = 0, TG_HDR_TP = 1, TG_HDR_tp = 2, TG_HDR_tP = 3, TG_HDR_Tp = 4 };

typedef struct tg_frame {
    uint8_t header;         /* enum tg_header */
    char src, dst;          /* address letters U M D E P G */
    char rw;                /* 'r', 'w', or 0 for #Tp frames */
    char ident[3];          /* identifier, not NUL-terminated */
    const uint8_t *data;    /* data bytes (points into the parser's buffer or the caller's) */
    uint16_t len;           /* number of data bytes */
    int16_t declared;       /* length on the wire when it differs from len (recovered), else -1 */
} tg_frame;

/* Sum of the bytes mod 256 (the TOP checksum). p may be NULL when n is 0. */
uint8_t tg_checksum(const uint8_t *p, size_t n);
/* Write a whole frame (header..checksum); returns its length or TG_E_SPACE / TG_E_ARG /
 * TG_E_RANGE (a length the header cannot carry). f->data: f->len bytes (NULL when 0); it may
 * already sit at out + 10. Nothing is written on an error. */
int tg_frame_write(const tg_frame *f, uint8_t *out, size_t cap);
/* The 3-character header text of a header code ("#TP"...), NULL when invalid. */
const char *tg_header_text(uint8_t header);

/* ---- streaming parser --------------------------------------------------------------------- */

enum tg_diag {
    TG_DIAG_GARBAGE = 1,
    TG_DIAG_BAD_HEADER,
    TG_DIAG_BAD_LENGTH,
    TG_DIAG_OVERSIZE,
    TG_DIAG_BAD_CHECKSUM,
    TG_DIAG_LENGTH_MISMATCH
};

enum tg_reason {
    TG_R_NONE = 0,
    TG_R_OUTSIDE,             /* bytes outside a frame */
    TG_R_BAD_HEADER,          /* '#' not followed by a valid header/address/length */
    TG_R_OVERSIZE,            /* declared length above the bound */
    TG_R_INCOMPLETE_FOLLOWED, /* incomplete frame followed by a good one */
    TG_R_END_OF_STREAM,       /* incomplete frame at end of stream */
    TG_R_INNER_FRAME,         /* checksum matched by chance: a frame starts inside */
    TG_R_BAD_CHECKSUM,        /* checksum wrong */
    TG_R_LENGTH_MISMATCH      /* length character wrong; checksum proves the real length */
};

typedef struct tg_scan_cfg {
    uint32_t max_data;      /* bound on the declared data length */
    uint8_t recover_length; /* accept a wrong ASCII length character when the checksum proves it */
} tg_scan_cfg;

enum tg_step_kind {
    TG_STEP_WAIT = 0,     /* more bytes needed from `next` on */
    TG_STEP_FRAME,        /* a good frame [start, end) */
    TG_STEP_RECOVERED,    /* a good frame with a wrong length character [start, end) */
    TG_STEP_DISCARD,      /* bytes [start, end) dropped (diag says which kind) */
    TG_STEP_BAD_CHECKSUM  /* a frame [start, end) with a wrong checksum; resume at next */
};

typedef struct tg_step {
    uint8_t kind;      /* enum tg_step_kind */
    uint8_t diag;      /* enum tg_diag for DISCARD / BAD_CHECKSUM */
    uint8_t reason;    /* enum tg_reason */
    uint8_t wake_mark; /* WAIT: rescan when '#', CR or LF arrives */
    size_t start, end; /* bytes concerned */
    size_t next;       /* where scanning resumes (WAIT: the first byte to keep) */
    size_t wake_len;   /* WAIT: nothing can change before the buffer holds this many bytes */
    int declared;      /* RECOVERED: the length character's value */
} tg_step;

/* One step of the scanner over buf[0..n) from `pos` (pure: no state). `final` means no more bytes
 * will come (end of a datagram or file). The same function drives the streaming parser below and
 * the Python fast path, so both behave as topgimbal.protocol.FrameParser. A pos at or past n is
 * a WAIT step. */
void tg_scan_step(const uint8_t *buf, size_t n, size_t pos, int final, const tg_scan_cfg *cfg, tg_step *out);
/* Fill a frame view from a FRAME / RECOVERED step over buf (only those kinds: other steps do not
 * describe a frame). */
void tg_step_frame(const uint8_t *buf, const tg_step *st, tg_frame *f);

typedef struct tg_parser_stats {
    uint32_t frames, bytes, bad_checksums, resyncs, bytes_discarded, length_recoveries, oversize;
} tg_parser_stats;

enum tg_event_type { TG_EV_NONE = 0, TG_EV_FRAME = 1, TG_EV_DIAG = 2 };

typedef struct tg_event {
    uint8_t type;         /* enum tg_event_type */
    uint8_t diag;         /* enum tg_diag (TG_EV_DIAG) */
    uint8_t reason;       /* enum tg_reason (TG_EV_DIAG) */
    tg_frame frame;       /* TG_EV_FRAME */
    const uint8_t *raw;   /* the bytes concerned (frame bytes, or discarded bytes) */
    size_t raw_len;
} tg_event;

typedef struct tg_parser {
    tg_scan_cfg cfg;
    tg_parser_stats stats;
    size_t len;        /* bytes in buf */
    size_t pos;        /* scan position */
    size_t wake_len;   /* see tg_step.wake_len */
    uint8_t wake_mark;
    uint8_t idle;      /* 1 while nothing can change until wake conditions */
    uint8_t final;     /* flushing: the stream ends at final_len */
    uint8_t pending;   /* a recovered frame follows its diagnostic */
    size_t final_len;  /* bytes fed before tg_parser_flush (those after it are a new stream) */
    tg_step pending_step;
    uint8_t buf[TG_PARSER_BUF];
} tg_parser;

/* cfg NULL: bound TG_PARSER_MAX_DATA, length recovery on. A larger max_data is clamped to
 * TG_PARSER_MAX_DATA. Statistics start at 0. */
void tg_parser_init(tg_parser *p, const tg_scan_cfg *cfg);
/* Drop the buffered bytes and any pending event (mid-frame too); keeps cfg and statistics. The
 * parser has no error state: after any diagnostic it simply goes on, no reset needed. */
void tg_parser_reset(tg_parser *p);
/* Room for tg_parser_feed right now. */
size_t tg_parser_space(const tg_parser *p);
/* Add one byte (returns 0 if the buffer is full: drain events first). */
int tg_parser_push(tg_parser *p, uint8_t byte);
/* Add up to n bytes; returns how many were taken (0 when full: drain events first). data may be
 * NULL when n is 0. */
size_t tg_parser_feed(tg_parser *p, const uint8_t *data, size_t n);
/* The next event, 1 if one was written to *ev, 0 when more bytes are needed. Pointers in *ev stay
 * valid until the next call to any tg_parser_* function. */
int tg_parser_next(tg_parser *p, tg_event *ev);
/* End of a datagram or stream: what remains is resolved by the following tg_parser_next calls
 * (a trailing frame with a wrong length character is recovered, the rest discarded). Bytes fed
 * after the flush, before those calls, start a new stream (as if fed after them); a second flush
 * before they return 0 moves the end of the flushed stream to the later point. */
void tg_parser_flush(tg_parser *p);

/* ---- values and codecs -------------------------------------------------------------------- */

enum tg_kind {
    TG_K_HEXINT = 1, TG_K_DECINT, TG_K_BININT, TG_K_DECFLOAT, TG_K_BITRATE, TG_K_ENUM, TG_K_ONEOF,
    TG_K_TEXT, TG_K_IPV4, TG_K_RAW, TG_K_LITERAL, TG_K_GEODM, TG_K_GEODEG, TG_K_TIMESTAMP
};

enum tg_vtype {
    TG_V_ABSENT = 0, /* encode: use the field's default */
    TG_V_NUM,        /* num * 10^exp10 */
    TG_V_NULL,       /* "no value" (a none token such as NNNNN or ERR) */
    TG_V_ENUM,       /* num = index into the codec's values */
    TG_V_TEXT,       /* text / ipv4 / literal: bytes at ptr, len */
    TG_V_BYTES,      /* raw bytes at ptr, len */
    TG_V_TIME        /* time.* */
};

typedef struct tg_time {
    uint16_t year;
    uint8_t month, day, hour, minute, second, centis;
} tg_time;

typedef struct tg_value {
    uint8_t type;      /* enum tg_vtype */
    int8_t exp10;
    uint16_t len;
    int64_t num;
    const uint8_t *ptr;
    tg_time time;
} tg_value;

typedef struct tg_spelling {
    const char *raw; /* `width` characters */
    uint8_t value;   /* index into values */
} tg_spelling;

typedef struct tg_codec {
    uint8_t kind;        /* enum tg_kind */
    uint8_t width;       /* fixed width, 0 when variable */
    uint8_t min_width, max_width;
    uint8_t is_signed, little, lat, binary, pyfloat; /* binary: raw data may hold '#', CR, LF */
    int8_t exp10;
    uint8_t decimals, pad;
    uint8_t n_values, n_spellings, n_none;
    int32_t mul;
    int64_t lo, hi;                 /* encode range, in mantissa units */
    const char *const *names;       /* enum value names */
    const char *const *raws;        /* enum canonical spellings */
    const uint8_t *idempotent;      /* enum: 0 for toggles / relative steps */
    const tg_spelling *spellings;   /* enum: accepted spellings (decode) */
    const char *const *none_tokens; /* spellings meaning "no value" */
    const char *text;               /* literal text, timestamp layout */
    const struct tg_codec *sub;     /* oneof: the number codec */
} tg_codec;

/* Decode one field. TG_OK, TG_E_INVALID or TG_E_UNSURE (see docs/c.md: the C core decodes a
 * strict subset of what the Python codecs accept; never a different value). raw may be NULL when
 * len is 0; *out is meaningful only on TG_OK (text and bytes point into raw). */
int tg_codec_decode(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out);
/* Encode one field; returns the number of bytes written or a negative tg_status: TG_E_TYPE (a
 * value type the field does not take, or not in enum tg_vtype), TG_E_RANGE (out of range, an
 * enum index outside the table, an impossible time, text with bytes outside printable ASCII or
 * a '#'), TG_E_SPACE. Text/bytes values: ptr to len bytes (NULL when len is 0). out may be NULL
 * when cap is 0. */
int tg_codec_encode(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap);

/* ---- catalog ------------------------------------------------------------------------------ */

enum tg_direction { TG_REQUEST = 0, TG_RESPONSE = 1 };

typedef struct tg_field {
    const char *name;
    const tg_codec *codec;
    uint8_t offset;      /* position in the data (the variable field is last) */
    int8_t sign;         /* fixed wire sign (-1: e.g. TOPOTEK UAV pitch is down-positive) */
    char axis;           /* 'y', 'p', 'r' for gimbal axes (model wire signs apply), 0 otherwise */
    const char *def_raw; /* default (as wire bytes) used when encoding without a value */
    uint8_t def_len;
    uint8_t has_default;
} tg_field;

typedef struct tg_form {
    char rw;                  /* 'r' or 'w' */
    uint8_t direction;        /* enum tg_direction */
    uint8_t echo;             /* the device's echo of a write */
    uint8_t n_fields;
    uint16_t min_len, max_len, fixed_len;
    const tg_field *fields;
    const uint8_t *const_data; /* non-NULL for forms with constant data (queries "00") */
    uint16_t const_len;
} tg_form;

typedef struct tg_command {
    char ident[4];
    const char *name;
    char address;            /* default destination */
    uint8_t header;          /* header the document insists on, or TG_HDR_NONE */
    uint8_t n_forms;
    uint8_t flags;           /* TG_CMD_* */
    const tg_form *forms;
    /* decode order per [rw: 0 r, 1 w][direction]: form indices, the direction's own forms first */
    const uint8_t *order[2][2];
    uint8_t n_order[2][2];
} tg_command;

#define TG_CMD_DOCUMENTED 0x01u
#define TG_CMD_ECHO 0x02u
#define TG_CMD_REPEATABLE 0x04u
#define TG_CMD_MOTION 0x08u

typedef struct tg_dialect {
    const char *name;
    const tg_command *commands;
    uint16_t n_commands;
    uint8_t gimbal_header;     /* header for gimbal frames, or TG_HDR_NONE */
    uint8_t headers;           /* bit (1 << header) for each header the dialect uses */
    char host_address;
    uint16_t hash_size;        /* power of two */
    const uint16_t *hash;      /* ident hash -> command index + 1 (0: empty) */
} tg_dialect;

const tg_command *tg_command_find(const tg_dialect *d, const char ident[3]);
/* The n-th form (0-based) of a command for control rw and a direction, NULL when absent. */
const tg_form *tg_form_find(const tg_command *c, char rw, uint8_t direction, unsigned nth);

typedef struct tg_message {
    const tg_command *cmd;
    const tg_form *form;
    uint8_t n_fields;
    tg_value values[TG_CATALOG_MAX_FIELDS];
} tg_message;

/* Name the fields of a frame (the Python Dialect.decode): returns TG_OK, TG_E_UNKNOWN or
 * TG_E_NO_FORM. Text and byte values point into the frame's data. Any header, address, control
 * and identifier bytes are accepted (an unknown identifier is TG_E_UNKNOWN); f->data may be NULL
 * when f->len is 0. */
int tg_decode(const tg_dialect *d, const tg_frame *f, tg_message *m);
/* Decode data against one form: TG_OK, TG_E_INVALID, TG_E_UNSURE. values: room for
 * form->n_fields (the generated TG_CATALOG_MAX_FIELDS always fits); data may be NULL when len is 0. */
int tg_form_decode(const tg_form *form, const uint8_t *data, size_t len, tg_value *values);
/* Encode values (one per form field, TG_V_ABSENT for defaults; NULL for a form without fields)
 * as form data; returns the length or a negative tg_status (TG_E_ARG: a field without a default
 * left absent). out may be NULL when cap is 0. */
int tg_form_encode(const tg_form *form, const tg_value *values, uint8_t *out, size_t cap);
/* The header the dialect uses for a command with n data bytes to/from dst (Dialect.header_for). */
uint8_t tg_header_for(const tg_dialect *d, const tg_command *c, size_t n, char dst);
/* A whole frame: encode `values` with `form` (one of c's forms), header chosen by tg_header_for
 * when header is 0; returns the frame's length (at most 12 + TG_CATALOG_MAX_DATA) or a negative tg_status
 * (TG_E_ARG: an address other than U M D E P G, a header code outside enum tg_header). */
int tg_encode(const tg_dialect *d, const tg_command *c, const tg_form *form, char src, char dst,
              uint8_t header, const tg_value *values, uint8_t *out, size_t cap);

/* ---- value helpers ------------------------------------------------------------------------ */

static inline tg_value tg_num(int64_t mantissa, int exp10) {
    tg_value v;
    memset(&v, 0, sizeof v);
    v.type = TG_V_NUM;
    v.num = mantissa;
    v.exp10 = (int8_t)exp10;
    return v;
}
static inline tg_value tg_enum_value(unsigned index) {
    tg_value v;
    memset(&v, 0, sizeof v);
    v.type = TG_V_ENUM;
    v.num = (int64_t)index;
    return v;
}
/* Index of an enum value by name (NUL-terminated), -1 if none or the codec is not an enum. */
int tg_enum_find(const tg_codec *c, const char *name);
/* A number rescaled to 10^exp10 (rounded half to even): TG_OK, TG_E_TYPE (not a TG_V_NUM) or
 * TG_E_RANGE (the result does not fit in int64_t). *out is set only on TG_OK. */
int tg_value_rescale(const tg_value *v, int exp10, int64_t *out);

#ifdef __cplusplus
}
#endif
#endif /* TOPGIMBAL_H */
