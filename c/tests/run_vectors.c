/*
 * Checks libtopgimbal against vectors produced by the Python side (topgimbal/tools/cvectors.py):
 * decode, encode and streams (whole and byte at a time). Prints "N passed, N failed"; exits 1 on
 * any failure. The test program may use libc; the library does not.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tg_catalog.h"

#define MAX_LINE 65536
#define MAX_EVENTS 256

static unsigned passed, failed;

static const tg_dialect *dialect_named(const char *name) {
    if (strcmp(name, "skydroid") == 0) return &tg_skydroid;
    if (strcmp(name, "topotek") == 0) return &tg_topotek;
    return NULL;
}

static int unhex(const char *s, uint8_t *out, size_t cap) {
    size_t n = strlen(s), k;
    if (strcmp(s, "-") == 0) return 0;
    if (n % 2 || n / 2 > cap) return -1;
    for (k = 0; k < n / 2; k++) {
        unsigned v;
        if (sscanf(s + 2 * k, "%2x", &v) != 1) return -1;
        out[k] = (uint8_t)v;
    }
    return (int)(n / 2);
}

static int fail(unsigned line, const char *what, const char *detail) {
    failed++;
    if (failed <= 40) fprintf(stderr, "line %u: %s: %s\n", line, what, detail);
    return -1;
}

/* ---- values ------------------------------------------------------------------------------- */

typedef struct {
    uint8_t bytes[256];
} span_store;

static int parse_value(const char *tok, tg_value *v, span_store *store) {
    memset(v, 0, sizeof *v);
    if (strcmp(tok, "a") == 0) return 0;
    if (strcmp(tok, "z") == 0) {
        v->type = TG_V_NULL;
        return 0;
    }
    if (tok[0] == 'n' && tok[1] == ':') {
        long long m;
        int e;
        if (sscanf(tok + 2, "%llde%d", &m, &e) != 2) return -1;
        *v = tg_num(m, e);
        return 0;
    }
    if (tok[0] == 'e' && tok[1] == ':') {
        *v = tg_enum_value((unsigned)atoi(tok + 2));
        return 0;
    }
    if ((tok[0] == 't' || tok[0] == 'b') && tok[1] == ':') {
        int n = unhex(tok + 2, store->bytes, sizeof store->bytes);
        if (n < 0) return -1;
        v->type = tok[0] == 't' ? TG_V_TEXT : TG_V_BYTES;
        v->ptr = store->bytes;
        v->len = (uint16_t)n;
        return 0;
    }
    if (tok[0] == 'd' && tok[1] == ':') {
        unsigned y, mo, d, h, mi, s, c;
        if (sscanf(tok + 2, "%4u%2u%2u%2u%2u%2u%2u", &y, &mo, &d, &h, &mi, &s, &c) != 7) return -1;
        v->type = TG_V_TIME;
        v->time.year = (uint16_t)y;
        v->time.month = (uint8_t)mo;
        v->time.day = (uint8_t)d;
        v->time.hour = (uint8_t)h;
        v->time.minute = (uint8_t)mi;
        v->time.second = (uint8_t)s;
        v->time.centis = (uint8_t)c;
        return 0;
    }
    return -1;
}

static int same_value(const tg_value *a, const tg_value *b) {
    if (a->type != b->type) return 0;
    switch (a->type) {
    case TG_V_NUM: {
        int64_t x;
        if (tg_value_rescale(a, b->exp10, &x) != TG_OK) return 0;
        if (x != b->num) return 0;
        return tg_value_rescale(b, a->exp10, &x) == TG_OK && x == a->num;
    }
    case TG_V_ENUM: return a->num == b->num;
    case TG_V_TEXT:
    case TG_V_BYTES: return a->len == b->len && (a->len == 0 || memcmp(a->ptr, b->ptr, a->len) == 0);
    case TG_V_TIME: return memcmp(&a->time, &b->time, sizeof a->time) == 0;
    default: return 1;
    }
}

static void describe(const tg_value *v, char *out, size_t cap) {
    switch (v->type) {
    case TG_V_NUM: snprintf(out, cap, "n:%llde%d", (long long)v->num, v->exp10); break;
    case TG_V_ENUM: snprintf(out, cap, "e:%lld", (long long)v->num); break;
    case TG_V_NULL: snprintf(out, cap, "z"); break;
    case TG_V_TEXT: snprintf(out, cap, "t:%.*s", v->len, (const char *)v->ptr); break;
    case TG_V_BYTES: snprintf(out, cap, "b:(%u bytes)", v->len); break;
    case TG_V_TIME: snprintf(out, cap, "d:%04u-%02u-%02u", v->time.year, v->time.month, v->time.day); break;
    default: snprintf(out, cap, "type %u", v->type);
    }
}

/* ---- M: decode ---------------------------------------------------------------------------- */

static int one_frame(const uint8_t *raw, size_t n, tg_frame *f) {
    tg_scan_cfg cfg = {TG_CATALOG_MAX_DATA, 1};
    tg_step st;
    tg_scan_step(raw, n, 0, 1, &cfg, &st);
    if ((st.kind != TG_STEP_FRAME && st.kind != TG_STEP_RECOVERED) || st.end != n) return -1;
    tg_step_frame(raw, &st, f);
    return 0;
}

static int check_decode(unsigned line, char **tok, int ntok) {
    const tg_dialect *d = dialect_named(tok[1]);
    uint8_t raw[512];
    int n = unhex(tok[2], raw, sizeof raw), status = atoi(tok[3]), r, k, nv;
    tg_frame f;
    tg_message m;
    char a[96], b[96];
    if (!d || n < 0 || ntok < 6) return fail(line, "decode", "bad vector line");
    if (one_frame(raw, (size_t)n, &f)) return fail(line, "decode", "frame does not scan");
    r = tg_decode(d, &f, &m);
    if (r != status) {
        snprintf(a, sizeof a, "status %d, expected %d", r, status);
        return fail(line, "decode", a);
    }
    if (status != 0) {
        passed++;
        return 0;
    }
    if ((int)(m.form - m.cmd->forms) != atoi(tok[4])) {
        snprintf(a, sizeof a, "form %d, expected %s", (int)(m.form - m.cmd->forms), tok[4]);
        return fail(line, "decode", a);
    }
    nv = atoi(tok[5]);
    if (nv != m.n_fields || ntok != 6 + nv) return fail(line, "decode", "field count");
    for (k = 0; k < nv; k++) {
        tg_value want;
        span_store store;
        if (parse_value(tok[6 + k], &want, &store)) return fail(line, "decode", "bad value token");
        if (!same_value(&m.values[k], &want)) {
            describe(&m.values[k], a, sizeof a);
            describe(&want, b, sizeof b);
            {
                char msg[256];
                snprintf(msg, sizeof msg, "%s != %s (field %s)", a, b, m.form->fields[k].name);
                return fail(line, "decode", msg);
            }
        }
    }
    passed++;
    return 0;
}

/* ---- N: encode ---------------------------------------------------------------------------- */

static int check_encode(unsigned line, char **tok, int ntok) {
    const tg_dialect *d = dialect_named(tok[1]);
    int ci = atoi(tok[2]), fi = atoi(tok[3]), nv, k, n, got;
    uint8_t want[512], out[512];
    tg_value values[TG_CATALOG_MAX_FIELDS];
    static span_store stores[TG_CATALOG_MAX_FIELDS];
    const tg_command *c;
    char msg[160];
    if (!d || ci >= d->n_commands || ntok < 7) return fail(line, "encode", "bad vector line");
    c = &d->commands[ci];
    n = unhex(tok[5], want, sizeof want);
    nv = atoi(tok[6]);
    if (n < 0 || nv > TG_CATALOG_MAX_FIELDS || ntok != 7 + nv) return fail(line, "encode", "bad vector line");
    for (k = 0; k < nv; k++)
        if (parse_value(tok[7 + k], &values[k], &stores[k])) return fail(line, "encode", "bad value token");
    got = tg_encode(d, c, &c->forms[fi], tok[4][0], tok[4][1], 0, values, out, sizeof out);
    if (got != n || memcmp(out, want, (size_t)n) != 0) {
        snprintf(msg, sizeof msg, "%.3s form %d: got %d bytes '%.*s', expected '%.*s'", c->ident, fi, got,
                 got > 0 ? got : 0, (const char *)out, n, (const char *)want);
        return fail(line, "encode", msg);
    }
    { /* and the C decoder reads the C encoder's frame back as the values given */
        tg_frame f;
        tg_value back[TG_CATALOG_MAX_FIELDS];
        if (one_frame(out, (size_t)got, &f) || tg_form_decode(&c->forms[fi], f.data, f.len, back) != TG_OK) {
            snprintf(msg, sizeof msg, "%.3s form %d: '%.*s' does not decode with its form", c->ident, fi, got,
                     (const char *)out);
            return fail(line, "encode round trip", msg);
        }
        for (k = 0; k < nv; k++) {
            if (values[k].type == TG_V_ABSENT || same_value(&back[k], &values[k])) continue;
            {
                char a[48], b[48];
                describe(&back[k], a, sizeof a);
                describe(&values[k], b, sizeof b);
                snprintf(msg, sizeof msg, "%.3s form %d field %d: decoded %s, encoded %s", c->ident, fi, k, a, b);
            }
            return fail(line, "encode round trip", msg);
        }
    }
    passed++;
    return 0;
}

/* ---- S: streams --------------------------------------------------------------------------- */

static void event_text(const tg_event *ev, char *out, size_t cap) {
    size_t k, n;
    if (ev->type == TG_EV_FRAME) {
        const tg_frame *f = &ev->frame;
        n = (size_t)snprintf(out, cap, "F %u %c%c%c %.3s ", f->header, f->src, f->dst, f->rw ? f->rw : '-', f->ident);
        if (!f->len) n += (size_t)snprintf(out + n, cap - n, "-");
        for (k = 0; k < f->len && n + 3 < cap; k++) n += (size_t)snprintf(out + n, cap - n, "%02x", f->data[k]);
        if (f->declared >= 0)
            snprintf(out + n, cap - n, " %d", f->declared);
        else
            snprintf(out + n, cap - n, " -");
    } else {
        n = (size_t)snprintf(out, cap, "D %u ", ev->diag);
        if (!ev->raw_len) n += (size_t)snprintf(out + n, cap - n, "-");
        for (k = 0; k < ev->raw_len && n + 3 < cap; k++) n += (size_t)snprintf(out + n, cap - n, "%02x", ev->raw[k]);
    }
}

static tg_parser parser; /* a test program's convenience; the library itself holds no state */

static int collect(char (*got)[1200], int ng) {
    tg_event ev;
    while (tg_parser_next(&parser, &ev) && ng < MAX_EVENTS) event_text(&ev, got[ng++], sizeof got[0]);
    return ng;
}

static int check_stream(unsigned line, const uint8_t *stream, size_t n, char (*want)[1200], int nw, int bytewise) {
    static char got[MAX_EVENTS][1200];
    int ng = 0, k;
    size_t i;
    tg_scan_cfg cfg = {TG_CATALOG_MAX_DATA, 1};
    char msg[2600];
    tg_parser_init(&parser, &cfg);
    if (bytewise) {
        for (i = 0; i < n; i++) {
            tg_parser_push(&parser, stream[i]);
            ng = collect(got, ng);
        }
    } else {
        for (i = 0; i < n;) {
            i += tg_parser_feed(&parser, stream + i, n - i);
            ng = collect(got, ng);
        }
    }
    tg_parser_flush(&parser);
    ng = collect(got, ng);
    if (parser.stats.bytes != n) return fail(line, "stream", "byte count");
    for (k = 0; k < (ng > nw ? ng : nw); k++) {
        if (k >= ng || k >= nw || strcmp(got[k], want[k]) != 0) {
            snprintf(msg, sizeof msg, "%s event %d: got '%s', expected '%s'", bytewise ? "bytewise" : "whole", k,
                     k < ng ? got[k] : "(none)", k < nw ? want[k] : "(none)");
            return fail(line, "stream", msg);
        }
    }
    passed++;
    return 0;
}

/* ---- main --------------------------------------------------------------------------------- */

static int split(char *s, char **tok, int max) {
    int n = 0;
    char *p = strtok(s, " \n");
    while (p && n < max) {
        tok[n++] = p;
        p = strtok(NULL, " \n");
    }
    return n;
}

int main(int argc, char **argv) {
    static char buf[MAX_LINE], want[MAX_EVENTS][1200];
    static uint8_t stream[MAX_LINE / 2];
    char *tok[64];
    unsigned line = 0, stream_line = 0;
    int ntok, nw = 0, in_stream = 0, slen = 0;
    FILE *fp;
    if (argc != 2) {
        fprintf(stderr, "usage: %s VECTORS\n", argv[0]);
        return 2;
    }
    fp = fopen(argv[1], "r");
    if (!fp) {
        perror(argv[1]);
        return 2;
    }
    while (fgets(buf, sizeof buf, fp)) {
        line++;
        if (buf[0] == '#' || buf[0] == '\n') continue;
        if (in_stream) {
            if (buf[0] == '.') {
                check_stream(stream_line, stream, (size_t)slen, want, nw, 0);
                check_stream(stream_line, stream, (size_t)slen, want, nw, 1);
                in_stream = 0;
            } else if (nw < MAX_EVENTS) {
                buf[strcspn(buf, "\n")] = 0;
                size_t len = strlen(buf);
                if (len >= sizeof want[0]) len = sizeof want[0] - 1;
                memcpy(want[nw], buf, len);
                want[nw++][len] = 0;
            }
            continue;
        }
        ntok = split(buf, tok, 64);
        if (ntok < 1) continue;
        if (strcmp(tok[0], "M") == 0) {
            check_decode(line, tok, ntok);
        } else if (strcmp(tok[0], "N") == 0) {
            check_encode(line, tok, ntok);
        } else if (strcmp(tok[0], "S") == 0 && ntok == 3) {
            slen = unhex(tok[2], stream, sizeof stream);
            if (slen < 0) {
                fail(line, "stream", "bad hex");
                slen = 0;
            }
            in_stream = 1;
            nw = 0;
            stream_line = line;
        } else {
            fail(line, "vectors", "unknown line");
        }
    }
    fclose(fp);
    printf("%u passed, %u failed\n", passed, failed);
    return failed ? 1 : 0;
}
