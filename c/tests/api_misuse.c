/*
 * The public API under the misuse a flight-controller integrator might commit, built with ASan +
 * UBSan (make -C c misuse, and from pytest): every call returns a documented status, never writes
 * outside its buffer and never reads outside its input. Prints "N checks, N failed"; exits 1 on
 * any failure (the sanitizers abort on the first undefined behaviour).
 *
 *  - encode of every form of both dialects into buffers of every capacity below the frame's size
 *    (exact-size heap buffers: ASan sees one byte too many), and at the exact size;
 *  - encode of every field with huge, tiny, negative, fixed-point edge mantissas and exponents,
 *    every value type (and types outside the enum), enum indices outside the table, impossible
 *    times, non-ASCII and over-long text; what encodes must scan and decode again;
 *  - decode of every form with data of every length up to max_len + 3, and without data (NULL);
 *  - frames with bad headers, addresses, controls, identifiers, declared lengths, no data;
 *  - the streaming parser fed zero-length (and NULL) chunks, reset mid-frame, while idle and with
 *    a recovered frame pending, flushed when empty, filled to the brim, with odd configurations,
 *    and fed more bytes after a flush before its events are drained.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tg_catalog.h"

static unsigned checks, failures;

static void expect(int ok, const char *what, const char *detail) {
    checks++;
    if (!ok && ++failures <= 40) fprintf(stderr, "FAIL %s: %s\n", what, detail);
}

static int documented(int r) {
    return r >= TG_E_ARG && r <= TG_OK;
}

static const tg_dialect *const dialects[2] = {&tg_skydroid, &tg_topotek};
static const uint8_t letters[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789abcdefghijklmnopqrstuvwxyz";

/* A value every codec kind accepts (the lowest number, the first enum value, ...). */
static tg_value valid_value(const tg_codec *c) {
    tg_value v;
    memset(&v, 0, sizeof v);
    switch (c->kind) {
    case TG_K_ENUM:
    case TG_K_ONEOF: return tg_enum_value(0);
    case TG_K_TEXT:
        v.type = TG_V_TEXT;
        v.ptr = letters;
        v.len = c->min_width ? c->min_width : 1;
        return v;
    case TG_K_IPV4:
        v.type = TG_V_TEXT;
        v.ptr = (const uint8_t *)"10.0.0.1";
        v.len = 8;
        return v;
    case TG_K_RAW:
        v.type = TG_V_BYTES;
        v.ptr = letters;
        v.len = c->width ? c->width : (c->min_width ? c->min_width : 1);
        return v;
    case TG_K_LITERAL:
        v.type = TG_V_TEXT;
        v.ptr = (const uint8_t *)c->text;
        v.len = (uint16_t)strlen(c->text);
        return v;
    case TG_K_TIMESTAMP:
        v.type = TG_V_TIME;
        v.time.year = 2024;
        v.time.month = 2;
        v.time.day = 29;
        return v;
    case TG_K_BITRATE: return tg_num(c->lo, 0);
    default: return tg_num(c->lo, c->exp10);
    }
}

/* Every capacity below the frame's size is TG_E_SPACE, writing nothing past the capacity. */
static void encode_capacities(const tg_dialect *d, const tg_command *c, const tg_form *form, const tg_value *vals) {
    uint8_t want[TG_FRAME_MAX + 64];
    char msg[128];
    int need = tg_encode(d, c, form, 'U', c->address, 0, vals, want, sizeof want), got;
    size_t cap;
    snprintf(msg, sizeof msg, "%s %.3s form %d", d->name, c->ident, (int)(form - c->forms));
    expect(need > 0, "valid values encode", msg);
    if (need <= 0) return;
    for (cap = 0; cap <= (size_t)need; cap++) {
        uint8_t *b = malloc(cap ? cap : 1);
        got = tg_encode(d, c, form, 'U', c->address, 0, vals, cap ? b : NULL, cap);
        if (cap < (size_t)need)
            expect(got == TG_E_SPACE, "a short buffer is TG_E_SPACE", msg);
        else
            expect(got == need && memcmp(b, want, (size_t)need) == 0, "the exact size is enough", msg);
        free(b);
    }
    need = tg_form_encode(form, vals, want, sizeof want);
    for (cap = 0; need > 0 && cap < (size_t)need; cap++) {
        uint8_t *b = malloc(cap ? cap : 1);
        expect(tg_form_encode(form, vals, cap ? b : NULL, cap) == TG_E_SPACE, "form data: short buffer", msg);
        free(b);
    }
}

/* What an encode accepts must scan as one frame and decode with the same form. */
static void encodes_back(const tg_form *form, const uint8_t *out, int n, const char *msg) {
    tg_scan_cfg cfg = {TG_PARSER_MAX_DATA, 1};
    tg_value back[TG_CATALOG_MAX_FIELDS];
    tg_step st;
    tg_frame f;
    tg_scan_step(out, (size_t)n, 0, 1, &cfg, &st);
    expect(st.kind == TG_STEP_FRAME && st.end == (size_t)n, "an encoded frame scans", msg);
    if (st.kind != TG_STEP_FRAME) return;
    tg_step_frame(out, &st, &f);
    expect(tg_form_decode(form, f.data, f.len, back) == TG_OK, "an encoded frame decodes", msg);
}

static void hostile_values(const tg_dialect *d, const tg_command *c, const tg_form *form, tg_value *vals) {
    static const int64_t nums[] = {0, 1, -1, 5, -5, 50, -50, INT64_MAX, INT64_MIN, INT64_MIN + 1,
                                   999999999999999999LL, -999999999999999999LL};
    static const int exps[] = {0, 1, -1, -2, -7, -9, -18, -19, 18, 19, -128, 127};
    static const int64_t indices[] = {-1, 255, 256, 65535, INT64_MAX, INT64_MIN};
    static const uint8_t odd[] = {0xC3, 0xA9, 0x80, 0xFF, '#', '\r', '\n', 0};
    static uint8_t long_text[70000];
    uint8_t out[TG_FRAME_MAX];
    char msg[160];
    unsigned k, j, e;
    int r;
    memset(long_text, 'A', sizeof long_text);
    for (k = 0; k < form->n_fields; k++) {
        const tg_codec *codec = form->fields[k].codec;
        tg_value save = vals[k];
        snprintf(msg, sizeof msg, "%s %.3s form %d field %s", d->name, c->ident, (int)(form - c->forms),
                 form->fields[k].name);
        for (j = 0; j < sizeof nums / sizeof nums[0]; j++)
            for (e = 0; e < sizeof exps / sizeof exps[0]; e++) {
                vals[k] = tg_num(nums[j], exps[e]);
                r = tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out);
                expect(documented(r) || r > 0, "numbers: a documented status", msg);
                if (r > 0) encodes_back(form, out, r, msg);
            }
        for (j = 0; j < 7 + 3; j++) { /* every value type, then three outside enum tg_vtype */
            memset(&vals[k], 0, sizeof vals[k]);
            vals[k].type = (uint8_t)(j < 7 ? j : 200 + j);
            vals[k].ptr = odd;
            vals[k].len = 3;
            r = tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out);
            expect(documented(r) || r > 0, "types: a documented status", msg);
            if (j >= 7) expect(r < 0, "an unknown value type is refused", msg);
            if (r > 0) encodes_back(form, out, r, msg);
            vals[k].ptr = NULL; /* no bytes: a NULL pointer is allowed */
            vals[k].len = 0;
            r = tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out);
            expect(documented(r) || r > 0, "empty spans: a documented status", msg);
        }
        for (j = 0; j < sizeof indices / sizeof indices[0]; j++) {
            vals[k] = tg_enum_value(0);
            vals[k].num = indices[j];
            r = tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out);
            expect(r < 0 || codec->kind == TG_K_LITERAL, "an enum index outside the table is refused", msg);
        }
        memset(&vals[k], 0, sizeof vals[k]);
        vals[k].type = TG_V_TIME;
        memset(&vals[k].time, 0xFF, sizeof vals[k].time);
        expect(tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out) < 0, "an impossible time", msg);
        memset(&vals[k].time, 0, sizeof vals[k].time);
        expect(tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out) < 0, "year 0, month 0", msg);
        vals[k].type = TG_V_TEXT;
        vals[k].ptr = long_text;
        vals[k].len = 65535;
        expect(tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out) < 0, "text of 65535 bytes", msg);
        vals[k].type = TG_V_BYTES;
        expect(tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out) < 0, "bytes of 65535", msg);
        if (codec->kind == TG_K_TEXT) {
            vals[k].type = TG_V_TEXT;
            vals[k].ptr = odd;
            vals[k].len = codec->min_width > 2 ? codec->min_width : 2;
            if (vals[k].len > 7) vals[k].len = 7;
            expect(tg_encode(d, c, form, 'U', c->address, 0, vals, out, sizeof out) == TG_E_RANGE,
                   "non-ASCII text is TG_E_RANGE", msg);
        }
        vals[k] = save;
    }
}

static void decode_lengths(const tg_form *form) {
    tg_value vals[TG_CATALOG_MAX_FIELDS];
    unsigned len, t, i;
    for (len = 0; len <= (unsigned)form->max_len + 3 && len < 300; len++)
        for (t = 0; t < 8; t++) {
            uint8_t *b = malloc(len ? len : 1);
            int r;
            for (i = 0; i < len; i++) b[i] = (uint8_t)(t == 0 ? '0' : t == 1 ? 0xFF : t == 2 ? ' ' : rand());
            r = tg_form_decode(form, b, len, vals);
            expect(r == TG_OK || r == TG_E_INVALID || r == TG_E_UNSURE, "decode: a documented status", form->fields ? form->fields[0].name : "-");
            free(b);
        }
    /* no data at all, as a frame without data may carry it */
    t = (unsigned)tg_form_decode(form, NULL, 0, vals);
    expect((int)t == TG_OK || (int)t == TG_E_INVALID || (int)t == TG_E_UNSURE, "decode of NULL, 0", "-");
}

static void frames(void) {
    tg_frame f;
    tg_message m;
    uint8_t out[64];
    size_t cap;
    int h, r, d;
    memset(&f, 0, sizeof f);
    f.src = 'U';
    f.dst = 'G';
    f.rw = 'r';
    memcpy(f.ident, "GAC", 3);
    f.data = (const uint8_t *)"00";
    f.len = 2;
    f.declared = -1;
    for (h = 0; h < 8; h++) {
        f.header = (uint8_t)h;
        for (cap = 0; cap < 20; cap++) {
            uint8_t *b = malloc(cap ? cap : 1);
            r = tg_frame_write(&f, cap ? b : NULL, cap);
            expect(r <= (int)cap && (r > 0 || documented(r)), "frame_write: within the capacity", "header");
            free(b);
        }
    }
    f.header = TG_HDR_tp;
    f.declared = 16;
    expect(tg_frame_write(&f, out, sizeof out) == TG_E_RANGE, "declared 16 under #tp", "-");
    f.declared = -1;
    f.ident[0] = (char)0xC3;
    expect(tg_frame_write(&f, out, sizeof out) == TG_E_ARG, "a non-ASCII identifier", "-");
    f.ident[0] = 'G';
    f.rw = 'x';
    expect(tg_frame_write(&f, out, sizeof out) == TG_E_ARG, "control 'x'", "-");
    f.rw = 'r';
    f.src = 0;
    expect(tg_frame_write(&f, out, sizeof out) == TG_E_ARG, "source address 0", "-");
    f.src = 'U';
    f.data = NULL;
    f.len = 0;
    expect(tg_frame_write(&f, out, sizeof out) == 12, "a frame without data (NULL)", "-");
    for (d = 0; d < 2; d++) {
        tg_frame g = f;
        g.ident[0] = (char)0xFF;
        g.ident[1] = 0;
        g.ident[2] = '#';
        expect(tg_decode(dialects[d], &g, &m) == TG_E_UNKNOWN, "decode: an identifier of odd bytes", "-");
        memcpy(g.ident, "GAC", 3);
        r = tg_decode(dialects[d], &g, &m); /* GAC without data: NULL data, length 0 */
        expect(r == TG_OK || r == TG_E_NO_FORM, "decode: a known command without data", "-");
        g.rw = 0;
        g.src = g.dst = 0;
        r = tg_decode(dialects[d], &g, &m);
        expect(r == TG_OK || r == TG_E_NO_FORM, "decode: no control, no addresses", "-");
    }
    {
        const tg_command *c = &tg_skydroid.commands[TG_SKYDROID_GAC];
        tg_value none[1];
        memset(none, 0, sizeof none);
        for (h = 0; h < 10; h++) {
            r = tg_encode(&tg_skydroid, c, &c->forms[0], 'U', 'G', (uint8_t)h, none, out, sizeof out);
            expect(r > 0 || documented(r), "encode with header code 0..9", "-");
        }
        expect(tg_encode(&tg_skydroid, c, &c->forms[0], 'X', 'G', 0, none, out, sizeof out) == TG_E_ARG, "src X", "-");
        expect(tg_encode(&tg_skydroid, c, &c->forms[0], 'U', 0, 0, none, out, sizeof out) == TG_E_ARG, "dst 0", "-");
    }
    expect(tg_header_text(200) == NULL, "header text of 200", "-");
    expect(tg_checksum(NULL, 0) == 0, "checksum of nothing", "-");
    expect(strstr(tg_status_text(TG_E_SPACE), "TG_E_SPACE") != NULL, "status text", "-");
    expect(strcmp(tg_status_text(-99), "unknown status") == 0, "status text of -99", "-");
}

static int drain(tg_parser *p, int *frames_seen) {
    tg_event ev;
    int n = 0;
    while (tg_parser_next(p, &ev)) {
        n++;
        if (ev.type == TG_EV_FRAME && frames_seen) (*frames_seen)++;
    }
    return n;
}

static void parser(void) {
    static tg_parser p;
    static const uint8_t frame[] = "#TPUD2wCAP013E";
    const size_t flen = sizeof frame - 1;
    tg_event ev;
    int n = 0, events;
    unsigned i, taken = 0;
    tg_parser_init(&p, NULL);
    expect(tg_parser_feed(&p, NULL, 0) == 0, "a zero-length chunk at NULL", "-");
    expect(tg_parser_feed(&p, frame, 0) == 0, "a zero-length chunk", "-");
    expect(drain(&p, NULL) == 0 && p.stats.bytes == 0, "nothing from nothing", "-");
    tg_parser_feed(&p, frame, 5);
    drain(&p, NULL);
    tg_parser_reset(&p); /* mid-frame */
    tg_parser_feed(&p, frame, flen);
    drain(&p, &n);
    expect(n == 1, "reset mid-frame: the next frame is whole", "-");
    tg_parser_feed(&p, (const uint8_t *)"#tpUG9wGAM123", 13); /* idle: waiting for 9 data bytes */
    drain(&p, NULL);
    tg_parser_reset(&p);
    n = 0;
    tg_parser_feed(&p, frame, flen);
    drain(&p, &n);
    expect(n == 1, "reset while waiting: the next frame is whole", "-");
    tg_parser_feed(&p, (const uint8_t *)"#TPUD3wCAP013E\r\n", 16); /* a wrong length character */
    if (tg_parser_next(&p, &ev)) tg_parser_reset(&p);            /* its frame is pending */
    expect(drain(&p, NULL) == 0, "reset drops a pending recovered frame", "-");
    tg_parser_flush(&p);
    tg_parser_flush(&p);
    expect(drain(&p, NULL) == 0, "an empty flush, twice", "-");
    for (i = 0; i < 5000; i++) taken += (unsigned)tg_parser_push(&p, 'x');
    expect(taken == sizeof p.buf, "push stops at the buffer's size", "-");
    events = drain(&p, NULL);
    expect(events >= 1 && p.len < sizeof p.buf, "a full buffer drains", "-");
    n = 0; /* the parser goes on after garbage, a bad checksum and an oversize claim */
    tg_parser_feed(&p, (const uint8_t *)"#TPUD2wCAP0100#tPUDFFwCAP", 25);
    tg_parser_feed(&p, frame, flen);
    drain(&p, &n);
    tg_parser_flush(&p);
    drain(&p, &n);
    expect(n == 1, "a frame after errors", "-");
    {
        tg_scan_cfg cfg = {0, 0};
        tg_parser_init(&p, &cfg);
        tg_parser_feed(&p, frame, flen);
        n = 0;
        drain(&p, &n);
        expect(n == 0, "max_data 0 takes no frame with data", "-");
        cfg.max_data = 0xFFFFFFFFu;
        cfg.recover_length = 7;
        tg_parser_init(&p, &cfg);
        expect(p.cfg.max_data == TG_PARSER_MAX_DATA, "max_data is clamped", "-");
        tg_parser_feed(&p, frame, flen);
        n = 0;
        drain(&p, &n);
        expect(n == 1, "a huge max_data still parses", "-");
    }
}

/* Events as text, for comparing two ways of feeding the same bytes. */
static size_t drain_text(tg_parser *p, char *out, size_t cap, size_t n) {
    tg_event ev;
    while (tg_parser_next(p, &ev)) {
        int w = snprintf(out + n, cap - n, "%c%u:%.*s|", ev.type == TG_EV_FRAME ? 'F' : 'D', ev.diag,
                         (int)ev.raw_len, (const char *)ev.raw);
        if (w > 0 && (size_t)w < cap - n) n += (size_t)w;
    }
    return n;
}

/* Bytes fed after tg_parser_flush and before the events are drained start a new stream: the same
 * events as draining first. (They used to be read as part of the flushed stream: a frame split
 * across that feed was discarded as the stream's unfinished end.) */
static void flush_then_feed(void) {
    static const char *const parts[] = {"#TPUD2wCAP013E", "#TPUD3wCAP013E", "#tpUG9wGAM", "123", "xyz", "\r\n",
                                        "#", "#TPUD2wCA", "P013E", "#tPUD02wCAP00", "5A"};
    static tg_parser a, b;
    static char ta[4096], tb[4096];
    unsigned round, i;
    for (round = 0; round < 3000; round++) {
        size_t na = 0, nb = 0;
        tg_parser_init(&a, NULL);
        tg_parser_init(&b, NULL);
        for (i = 0; i < 12; i++) {
            const char *part = parts[rand() % (int)(sizeof parts / sizeof parts[0])];
            size_t len = strlen(part);
            if (rand() % 3 == 0) { /* a flush, then this part: drained after (a), before (b) */
                tg_parser_flush(&a);
                tg_parser_feed(&a, (const uint8_t *)part, len);
                na = drain_text(&a, ta, sizeof ta, na);
                tg_parser_flush(&b);
                nb = drain_text(&b, tb, sizeof tb, nb);
                tg_parser_feed(&b, (const uint8_t *)part, len);
                nb = drain_text(&b, tb, sizeof tb, nb);
            } else {
                tg_parser_feed(&a, (const uint8_t *)part, len);
                na = drain_text(&a, ta, sizeof ta, na);
                tg_parser_feed(&b, (const uint8_t *)part, len);
                nb = drain_text(&b, tb, sizeof tb, nb);
            }
        }
        expect(na == nb && memcmp(ta, tb, na) == 0 && a.stats.frames == b.stats.frames,
               "bytes fed after a flush start a new stream", na == nb ? tb : ta);
    }
}

static void rescale(void) {
    static const int64_t nums[] = {0, 1, -1, 5, -5, 15, -15, INT64_MAX, INT64_MIN, INT64_MIN + 1};
    tg_value v;
    int64_t out;
    unsigned j;
    int a, b, r;
    for (j = 0; j < sizeof nums / sizeof nums[0]; j++)
        for (a = -128; a <= 127; a++)
            for (b = -128; b <= 127; b += 5) {
                v = tg_num(nums[j], a);
                r = tg_value_rescale(&v, b, &out);
                expect(r == TG_OK || r == TG_E_RANGE, "rescale: a documented status", "-");
            }
    memset(&v, 0, sizeof v);
    v.type = TG_V_ENUM;
    expect(tg_value_rescale(&v, 0, &out) == TG_E_TYPE, "rescale of an enum", "-");
}

int main(void) {
    unsigned di, ci, fi, k;
    srand(1);
    frames();
    parser();
    flush_then_feed();
    rescale();
    for (di = 0; di < 2; di++) {
        const tg_dialect *d = dialects[di];
        for (ci = 0; ci < d->n_commands; ci++) {
            const tg_command *c = &d->commands[ci];
            for (fi = 0; fi < c->n_forms; fi++) {
                const tg_form *form = &c->forms[fi];
                tg_value vals[TG_CATALOG_MAX_FIELDS];
                memset(vals, 0, sizeof vals);
                for (k = 0; k < form->n_fields; k++) vals[k] = valid_value(form->fields[k].codec);
                encode_capacities(d, c, form, vals);
                hostile_values(d, c, form, vals);
                decode_lengths(form);
            }
        }
    }
    printf("%u checks, %u failed\n", checks, failures);
    return failures ? 1 : 0;
}
