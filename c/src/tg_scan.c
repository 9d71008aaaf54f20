/*
 * The frame scanner: one step of topgimbal.protocol.FrameParser._scan as a pure function.
 *
 * It mirrors the Python parser branch for branch (resync at '#', an identifier of 3 ASCII letters or
 * digits, a good frame never held back by garbage before it, a frame whose checksum matched by
 * chance yielding to the first valid frame that starts inside it, exact-fit length recovery for a
 * wrong ASCII length character, a bound on the declared length), so the streaming parser (tg_parser.c) and the Python fast path, which both
 * drive it, agree with the pure Python parser frame for frame. Keep the two side by side when
 * either changes; the differential tests compare them.
 */
#include "tg_internal.h"

#define ASCII_MAX_TOTAL (12 + 15)
#define END_INVALID (-1L)
#define END_NEED (-2L)
#define END_OVERSIZE (-3L)

static int hexval(uint8_t c) { return tg_hexval[c]; }

static int is_addr(uint8_t c) {
    return c == 'U' || c == 'M' || c == 'D' || c == 'E' || c == 'P' || c == 'G';
}

static int is_ident(uint8_t c) {
    return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}

static int is_rw(uint8_t c) { return c == 'r' || c == 'w'; }

static uint8_t header_code(uint8_t a, uint8_t b) {
    if (a == 'T') return b == 'P' ? TG_HDR_TP : (b == 'p' ? TG_HDR_Tp : TG_HDR_NONE);
    if (a == 't') return b == 'p' ? TG_HDR_tp : (b == 'P' ? TG_HDR_tP : TG_HDR_NONE);
    return TG_HDR_NONE;
}

static uint8_t upper(uint8_t c) { return (c >= 'a' && c <= 'z') ? (uint8_t)(c - 32) : c; }

static uint8_t hexdigit(unsigned v) { return (uint8_t)(v < 10 ? '0' + v : 'A' + v - 10); }

static uint8_t sum8(const uint8_t *p, size_t n) {
    unsigned s = 0;
    size_t k;
    for (k = 0; k < n; k++) s += p[k];
    return (uint8_t)s;
}

static long find_hash(const uint8_t *buf, size_t from, size_t to) {
    const void *q;
    size_t k;
    if (from >= to) return -1;
    if (to - from > 64) {
        q = memchr(buf + from, '#', to - from);
        return q ? (long)((const uint8_t *)q - buf) : -1;
    }
    for (k = from; k < to; k++) /* spans of a frame or two: a loop beats a library call */
        if (buf[k] == '#') return (long)k;
    return -1;
}

/* The Python parser's _bad_prefix: bytes already after '#' that rule a frame out. */
static int bad_prefix(const uint8_t *buf, size_t n, size_t i) {
    uint8_t hdr;
    size_t k;
    if (n <= i + 2) return n > i + 1 && buf[i + 1] != 'T' && buf[i + 1] != 't';
    hdr = header_code(buf[i + 1], buf[i + 2]);
    if (hdr == TG_HDR_NONE) return 1;
    for (k = 3; k <= 4; k++)
        if (n > i + k && !is_addr(buf[i + k])) return 1;
    if (n > i + 5 && (hdr == TG_HDR_TP || hdr == TG_HDR_tp) && hexval(buf[i + 5]) < 0) return 1;
    if (n > i + 6 && hdr != TG_HDR_Tp && !is_rw(buf[i + 6])) return 1;
    for (k = 7; k <= 9; k++)
        if (n > i + k && !is_ident(buf[i + k])) return 1;
    return 0;
}

/* End offset of a frame starting at i by its declared length; END_* otherwise (the Python
 * parser's _frame_end). */
static long frame_end(const uint8_t *buf, size_t n, size_t i, uint32_t max_data) {
    uint8_t hdr;
    long len;
    if (n < i + 10) return bad_prefix(buf, n, i) ? END_INVALID : END_NEED;
    hdr = header_code(buf[i + 1], buf[i + 2]);
    if (hdr == TG_HDR_NONE || !is_addr(buf[i + 3]) || !is_addr(buf[i + 4]) || !is_ident(buf[i + 7]) ||
        !is_ident(buf[i + 8]) || !is_ident(buf[i + 9]))
        return END_INVALID;
    if (hdr == TG_HDR_TP || hdr == TG_HDR_tp) {
        len = hexval(buf[i + 5]);
        if (len < 0 || !is_rw(buf[i + 6])) return END_INVALID;
    } else if (hdr == TG_HDR_tP) {
        len = buf[i + 5];
        if (!is_rw(buf[i + 6])) return END_INVALID;
    } else {
        len = ((long)buf[i + 5] << 8) | buf[i + 6];
    }
    if ((unsigned long)len > max_data) return END_OVERSIZE;
    return (long)i + 12 + len;
}

/* Checksum as written (all upper or all lower case hex), the hot path's test; *hash_inside says
 * whether a '#' follows the frame's own (the summing loop looks anyway). */
static int crc_ok_exact(const uint8_t *buf, size_t start, size_t end, int *hash_inside) {
    unsigned sum = buf[start], found = 0;
    size_t k;
    uint8_t s, hi, lo;
    for (k = start + 1; k < end - 2; k++) {
        sum += buf[k];
        found |= buf[k] == '#';
    }
    *hash_inside = (int)found;
    s = (uint8_t)sum;
    hi = hexdigit(s >> 4);
    lo = hexdigit(s & 15);
    uint8_t a = buf[end - 2], b = buf[end - 1];
    if (a == hi && b == lo) return 1;
    if (hi >= 'A') hi = (uint8_t)(hi + 32);
    if (lo >= 'A') lo = (uint8_t)(lo + 32);
    return a == hi && b == lo;
}

/* Checksum in any letter case (the Python parser's .upper() comparisons). */
static int crc_ok_upper(const uint8_t *buf, size_t start, size_t end) {
    uint8_t s = sum8(buf + start, end - 2 - start);
    return upper(buf[end - 2]) == hexdigit(s >> 4) && upper(buf[end - 1]) == hexdigit(s & 15);
}

static int valid_complete_at(const uint8_t *buf, size_t n, size_t j, uint32_t max_data) {
    long end = frame_end(buf, n, j, max_data);
    if (end < 0 || (size_t)end > n) return 0;
    return crc_ok_upper(buf, j, (size_t)end);
}

/* Python _recover: 1 found (*rec_end, *declared), 0 none, -1 bytes to come decide. */
static int recover(const uint8_t *buf, size_t n, size_t i, int final, size_t *rec_end, int *declared) {
    size_t limit = n < i + ASCII_MAX_TOTAL ? n : i + ASCII_MAX_TOTAL;
    size_t boundary = 0, k;
    int found = 0;
    long len;
    for (k = i + 1; k < limit; k++) {
        uint8_t b = buf[k];
        if (b == '#' || b == '\r' || b == '\n') {
            boundary = k;
            found = 1;
            break;
        }
    }
    if (!found) {
        if (!final && n < i + ASCII_MAX_TOTAL) return -1;
        boundary = limit;
    }
    len = (long)boundary - (long)i - 12;
    *declared = hexval(buf[i + 5]);
    if (len < 0 || len > 15 || len == *declared) return 0;
    if (!crc_ok_upper(buf, i, boundary)) return 0;
    for (k = i + 10; k < boundary - 2; k++)
        if (buf[k] < 0x20 || buf[k] >= 0x7F) return 0;
    *rec_end = boundary;
    return 1;
}

/* Python _inner_frame, for a frame [i, end) whose checksum is right: the start of the first valid
 * frame that begins inside it (then the outer one matched by chance and yields), -1 when there is
 * none, -2 when bytes still to come decide (a candidate inside runs past the buffer). */
static long inner_frame(const uint8_t *buf, size_t n, size_t i, size_t end, int final, uint32_t max_data) {
    long j = find_hash(buf, i + 1, end);
    while (j >= 0) {
        long e = frame_end(buf, n, (size_t)j, max_data);
        if (e == END_NEED || e > (long)n) {
            if (!final) return -2;
        } else if (e > 0 && crc_ok_upper(buf, (size_t)j, (size_t)e)) {
            return j;
        }
        j = find_hash(buf, (size_t)j + 1, end);
    }
    return -1;
}

static void set(tg_step *o, uint8_t kind, uint8_t diag, uint8_t reason, size_t start, size_t end, size_t next) {
    o->kind = kind;
    o->diag = diag;
    o->reason = reason;
    o->start = start;
    o->end = end;
    o->next = next;
}

static void wait(tg_step *o, size_t at, size_t wake_len, int wake_mark) {
    set(o, TG_STEP_WAIT, 0, TG_R_NONE, at, at, at);
    o->wake_len = wake_len;
    o->wake_mark = (uint8_t)wake_mark;
}

void tg_scan_step(const uint8_t *buf, size_t n, size_t pos, int final, const tg_scan_cfg *cfg, tg_step *o) {
    long i, end, j;
    uint8_t hdr;
    int ascii_hdr, declared, r;
    size_t rec_end;
    memset(o, 0, sizeof *o);
    if (pos >= n) {
        wait(o, n, n + 1, 1);
        return;
    }
    i = buf[pos] == '#' ? (long)pos : find_hash(buf, pos, n);
    if (i < 0) {
        set(o, TG_STEP_DISCARD, TG_DIAG_GARBAGE, TG_R_OUTSIDE, pos, n, n);
        return;
    }
    if ((size_t)i > pos) {
        set(o, TG_STEP_DISCARD, TG_DIAG_GARBAGE, TG_R_OUTSIDE, pos, (size_t)i, (size_t)i);
        return;
    }
    end = frame_end(buf, n, (size_t)i, cfg->max_data);
    if (end == END_NEED) {
        wait(o, (size_t)i, n + 1, 1);
        return;
    }
    if (end == END_INVALID) {
        set(o, TG_STEP_DISCARD, TG_DIAG_BAD_HEADER, TG_R_BAD_HEADER, (size_t)i, (size_t)i + 1, (size_t)i + 1);
        return;
    }
    if (end == END_OVERSIZE) {
        set(o, TG_STEP_DISCARD, TG_DIAG_OVERSIZE, TG_R_OVERSIZE, (size_t)i, (size_t)i + 1, (size_t)i + 1);
        return;
    }
    hdr = header_code(buf[i + 1], buf[i + 2]);
    ascii_hdr = hdr == TG_HDR_TP || hdr == TG_HDR_tp;
    if ((size_t)end > n) {
        /* Incomplete: wait, unless a complete good frame already follows. */
        long first = find_hash(buf, (size_t)i + 1, n);
        j = first;
        while (j >= 0 && !valid_complete_at(buf, n, (size_t)j, cfg->max_data)) j = find_hash(buf, (size_t)j + 1, n);
        if (j < 0) {
            /* Nothing changes before the declared end unless a '#' starts a frame after i. */
            if (first >= 0)
                wait(o, (size_t)i, n + 1, 1);
            else
                wait(o, (size_t)i, (size_t)end, 1);
            return;
        }
        if (cfg->recover_length && ascii_hdr) {
            if (recover(buf, n, (size_t)i, 1, &rec_end, &declared) == 1) {
                set(o, TG_STEP_RECOVERED, TG_DIAG_LENGTH_MISMATCH, TG_R_LENGTH_MISMATCH, (size_t)i, rec_end, rec_end);
                o->declared = declared;
                return;
            }
        }
        set(o, TG_STEP_DISCARD, TG_DIAG_GARBAGE, TG_R_INCOMPLETE_FOLLOWED, (size_t)i, (size_t)j, (size_t)j);
        return;
    }
    if (crc_ok_exact(buf, (size_t)i, (size_t)end, &r)) {
        /* the checksum characters matched hex digits: a '#' inside can only be in the data */
        j = r ? inner_frame(buf, n, (size_t)i, (size_t)end, final, cfg->max_data) : -1;
        if (j == -2) { /* the one documented wait: a '#' and a header inside binary data */
            wait(o, (size_t)i, n + 1, 1);
            return;
        }
        if (j >= 0) {
            set(o, TG_STEP_DISCARD, TG_DIAG_GARBAGE, TG_R_INNER_FRAME, (size_t)i, (size_t)j, (size_t)j);
            return;
        }
        set(o, TG_STEP_FRAME, 0, TG_R_NONE, (size_t)i, (size_t)end, (size_t)end);
        return;
    }
    /* Bad checksum at the declared length. */
    if (cfg->recover_length && ascii_hdr) {
        r = recover(buf, n, (size_t)i, final, &rec_end, &declared);
        if (r < 0) {
            wait(o, (size_t)i, (size_t)i + ASCII_MAX_TOTAL, 1);
            return;
        }
        if (r == 1) {
            set(o, TG_STEP_RECOVERED, TG_DIAG_LENGTH_MISMATCH, TG_R_LENGTH_MISMATCH, (size_t)i, rec_end, rec_end);
            o->declared = declared;
            return;
        }
    }
    j = find_hash(buf, (size_t)i + 1, (size_t)end);
    set(o, TG_STEP_BAD_CHECKSUM, TG_DIAG_BAD_CHECKSUM, TG_R_BAD_CHECKSUM, (size_t)i, (size_t)end,
        j >= 0 ? (size_t)j : (size_t)end);
}

void tg_step_frame(const uint8_t *buf, const tg_step *st, tg_frame *f) {
    const uint8_t *p = buf + st->start;
    f->header = header_code(p[1], p[2]);
    f->src = (char)p[3];
    f->dst = (char)p[4];
    f->rw = f->header == TG_HDR_Tp ? 0 : (char)p[6];
    f->ident[0] = (char)p[7];
    f->ident[1] = (char)p[8];
    f->ident[2] = (char)p[9];
    f->data = p + 10;
    f->len = (uint16_t)(st->end - st->start - 12);
    f->declared = (int16_t)(st->kind == TG_STEP_RECOVERED ? st->declared : -1);
}
