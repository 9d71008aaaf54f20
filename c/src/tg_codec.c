/*
 * Field codecs: one field's bytes <-> a tg_value in user units (fixed point), per codec kind.
 *
 * Decoding accepts a strict subset of what the Python codecs accept and never yields a different
 * value: where Python would parse a spelling the C core does not (an exponent in a decimal, a
 * space-padded date), the result is TG_E_UNSURE rather than a guess; TG_E_INVALID means Python
 * rejects the bytes too. Adding a codec kind: a case in tg_codec_decode and tg_codec_encode, and
 * a handler in src/topgimbal/_speedups/spec.py.
 */
#include "tg_internal.h"

#define MAX_TEXT 32

static const int64_t POW10[19] = {1LL,
                                  10LL,
                                  100LL,
                                  1000LL,
                                  10000LL,
                                  100000LL,
                                  1000000LL,
                                  10000000LL,
                                  100000000LL,
                                  1000000000LL,
                                  10000000000LL,
                                  100000000000LL,
                                  1000000000000LL,
                                  10000000000000LL,
                                  100000000000000LL,
                                  1000000000000000LL,
                                  10000000000000000LL,
                                  100000000000000000LL,
                                  1000000000000000000LL};

/* Hex digit values, -1 for anything else (a table: the scanner and hex fields read it per byte). */
const int8_t tg_hexval[256] = {
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
     0,  1,  2,  3,  4,  5,  6,  7,  8,  9, -1, -1, -1, -1, -1, -1,
    -1, 10, 11, 12, 13, 14, 15, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, 10, 11, 12, 13, 14, 15, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
    -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
};

static int hexval(uint8_t c) { return tg_hexval[c]; }

static int is_digit(uint8_t c) { return c >= '0' && c <= '9'; }

static uint8_t hexdigit(unsigned v) { return (uint8_t)(v < 10 ? '0' + v : 'A' + v - 10); }

static void clear(tg_value *v, uint8_t type) {
    memset(v, 0, sizeof *v);
    v->type = type;
}

static void set_num(tg_value *v, int64_t m, int exp10) {
    clear(v, TG_V_NUM);
    v->num = m;
    v->exp10 = (int8_t)exp10;
}

static int equals(const uint8_t *raw, size_t len, const char *s) {
    size_t n = strlen(s);
    return n == len && memcmp(raw, s, n) == 0;
}

static int is_none_token(const tg_codec *c, const uint8_t *raw, size_t len) {
    unsigned k;
    for (k = 0; k < c->n_none; k++)
        if (equals(raw, len, c->none_tokens[k])) return 1;
    return 0;
}

/* Rounded division, ties to even (the Python encoders' round()). */
static int64_t div_round(int64_t a, int64_t b) {
    int64_t q = a / b, r = a % b;
    int64_t twice;
    if (r < 0) r = -r;
    twice = 2 * r;
    if (twice > b || (twice == b && (q & 1))) q += (a < 0) ? -1 : 1;
    return q;
}

int tg_value_rescale(const tg_value *v, int exp10, int64_t *out) {
    int diff = v->exp10 - exp10;
    if (v->type != TG_V_NUM) return TG_E_TYPE;
    if (diff == 0) {
        *out = v->num;
    } else if (diff > 0) {
        if (diff > 18) return v->num == 0 ? (*out = 0, TG_OK) : TG_E_RANGE;
        if (v->num > INT64_MAX / POW10[diff] || v->num < -(INT64_MAX / POW10[diff])) return TG_E_RANGE;
        *out = v->num * POW10[diff];
    } else {
        if (-diff > 18) {
            *out = 0;
            return TG_OK;
        }
        *out = div_round(v->num, POW10[-diff]);
    }
    return TG_OK;
}

/* ---- enum tables -------------------------------------------------------------------------- */

static int enum_lookup(const tg_codec *c, const uint8_t *raw, size_t len) {
    unsigned k;
    if (len != c->width) return -1;
    for (k = 0; k < c->n_spellings; k++)
        if (memcmp(c->spellings[k].raw, raw, len) == 0) return c->spellings[k].value;
    return -1;
}

int tg_enum_find(const tg_codec *c, const char *name) {
    unsigned k;
    for (k = 0; k < c->n_values; k++)
        if (strcmp(c->names[k], name) == 0) return (int)k;
    return -1;
}

/* ---- decoders ----------------------------------------------------------------------------- */

static int dec_hexint(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    uint64_t v = 0;
    int64_t s;
    size_t k;
    if (is_none_token(c, raw, len)) {
        clear(out, TG_V_NULL);
        return TG_OK;
    }
    if (len != c->width || len > 15) return TG_E_INVALID;
    for (k = 0; k < len; k++) {
        int h = hexval(raw[k]);
        if (h < 0) return TG_E_INVALID;
        v = (v << 4) | (unsigned)h;
    }
    s = (int64_t)v;
    if (c->is_signed && len && (v >> (4 * len - 1)) & 1) s = (int64_t)v - ((int64_t)1 << (4 * len));
    set_num(out, s * c->mul, c->exp10);
    return TG_OK;
}

static int dec_decint(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    int64_t v = 0;
    size_t k;
    if (len != c->width || len == 0 || len > 18) return TG_E_INVALID;
    for (k = 0; k < len; k++) {
        if (!is_digit(raw[k])) return TG_E_INVALID;
        v = v * 10 + (raw[k] - '0');
    }
    set_num(out, v * c->mul, c->exp10);
    return TG_OK;
}

static int dec_binint(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    uint64_t v = 0;
    int64_t s;
    size_t k;
    if (len != c->width || len == 0 || len > 8) return TG_E_INVALID;
    for (k = 0; k < len; k++) v = (v << 8) | raw[c->little ? len - 1 - k : k];
    s = (int64_t)v;
    if (c->is_signed && len < 8 && (v >> (8 * len - 1)) & 1) s = (int64_t)v - ((int64_t)1 << (8 * len));
    set_num(out, s * c->mul, c->exp10);
    return TG_OK;
}

static int is_pyspace(uint8_t b) { return b == ' ' || b == '\t' || b == '\n' || b == '\r' || b == 0x0B || b == 0x0C; }

/* [spaces][+-]digits[.digits][spaces] with at most `decimals` fraction digits -> mantissa. */
static int parse_decimal(const uint8_t *p, size_t n, unsigned decimals, int64_t *m) {
    size_t a = 0, b = n;
    int neg = 0, digits = 0, frac = -1;
    int64_t v = 0;
    while (a < b && p[a] == ' ') a++;
    while (b > a && p[b - 1] == ' ') b--;
    if (a == b) return TG_E_INVALID;
    if (p[a] == '+' || p[a] == '-') neg = p[a++] == '-';
    for (; a < b; a++) {
        if (is_digit(p[a])) {
            if (digits >= 18) return TG_E_UNSURE;
            v = v * 10 + (p[a] - '0');
            digits++;
            if (frac >= 0) frac++;
        } else if (p[a] == '.' && frac < 0) {
            frac = 0;
        } else {
            return TG_E_UNSURE; /* exponent, underscore, inf, other whitespace: Python may read it */
        }
    }
    if (!digits) return TG_E_UNSURE;
    if (frac < 0) frac = 0;
    if ((unsigned)frac > decimals) return TG_E_UNSURE; /* Python rounds the binary value */
    v *= POW10[decimals - (unsigned)frac];             /* -0 is 0: the codecs add 0.0 */
    *m = neg ? -v : v;
    return TG_OK;
}

static int dec_decfloat(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    size_t a = 0, b = len, k;
    int64_t m;
    int r;
    unsigned t;
    while (a < b && is_pyspace(raw[a])) a++;
    while (b > a && is_pyspace(raw[b - 1])) b--;
    for (t = 0; t < c->n_none; t++) {
        size_t tl = strlen(c->none_tokens[t]), head = len < 3 ? len : 3;
        if ((tl == b - a && memcmp(raw + a, c->none_tokens[t], tl) == 0) ||
            (tl == head && memcmp(raw, c->none_tokens[t], tl) == 0)) {
            clear(out, TG_V_NULL);
            return TG_OK;
        }
    }
    if (c->width && len != c->width) return TG_E_INVALID;
    for (k = 0; k < len; k++)
        if (raw[k] >= 0x80) return TG_E_INVALID;
    r = parse_decimal(raw, len, c->decimals, &m);
    if (r != TG_OK) return r;
    set_num(out, m, -(int)c->decimals);
    return TG_OK;
}

static int all_digits(const uint8_t *p, size_t n) {
    size_t k;
    if (!n) return 0;
    for (k = 0; k < n; k++)
        if (!is_digit(p[k])) return 0;
    return 1;
}

static int64_t digits_value(const uint8_t *p, size_t n) {
    int64_t v = 0;
    size_t k;
    for (k = 0; k < n; k++) v = v * 10 + (p[k] - '0');
    return v;
}

/* 0M0000 or Kddddd (kbps), also 0M or M as some answers spell Mbps (errata E23). */
static int dec_bitrate(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    (void)c;
    if (len == 6 && (raw[0] == 'K' || raw[0] == 'k') && all_digits(raw + 1, 5)) {
        set_num(out, digits_value(raw + 1, 5), 0);
        return TG_OK;
    }
    if ((len == 2 || len == 6) && raw[0] == '0' && all_digits(raw + 1, len - 1)) {
        set_num(out, (raw[1] - '0') * 1000, 0);
        return TG_OK;
    }
    if (len == 1 && all_digits(raw, 1)) {
        set_num(out, (raw[0] - '0') * 1000, 0);
        return TG_OK;
    }
    return TG_E_INVALID;
}

static int dec_enum(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    int k = enum_lookup(c, raw, len);
    if (k < 0) return TG_E_INVALID;
    clear(out, TG_V_ENUM);
    out->num = k;
    return TG_OK;
}

static void set_span(tg_value *out, uint8_t type, const uint8_t *raw, size_t len) {
    clear(out, type);
    out->ptr = raw;
    out->len = (uint16_t)len;
}

/* Dotted IPv4 as Python's ipaddress reads it (no leading zeros); -> 32-bit value. */
static int parse_ipv4(const uint8_t *p, size_t n, uint32_t *addr) {
    size_t k = 0;
    int part;
    uint32_t a = 0;
    for (part = 0; part < 4; part++) {
        size_t start = k;
        unsigned v = 0;
        while (k < n && is_digit(p[k])) {
            v = v * 10 + (unsigned)(p[k] - '0');
            k++;
            if (k - start > 3) return TG_E_INVALID;
        }
        if (k == start || v > 255 || (k - start > 1 && p[start] == '0')) return TG_E_INVALID;
        a = (a << 8) | v;
        if (part < 3) {
            if (k >= n || p[k] != '.') return TG_E_INVALID;
            k++;
        }
    }
    if (k != n) return TG_E_INVALID;
    *addr = a;
    return TG_OK;
}

/* ASCII text with spaces removed (the geo codecs' replace(" ", "")); -1 if not ASCII. */
static int squeeze(const uint8_t *raw, size_t len, uint8_t *t) {
    size_t k;
    int n = 0;
    if (len > MAX_TEXT) return -1;
    for (k = 0; k < len; k++) {
        if (raw[k] >= 0x80) return -1;
        if (raw[k] != ' ') t[n++] = raw[k];
    }
    return n;
}

static int hemisphere(const tg_codec *c, uint8_t h) {
    if (h >= 'a' && h <= 'z') h = (uint8_t)(h - 32);
    if (c->lat) return h == 'N' ? 1 : (h == 'S' ? -1 : 0);
    return h == 'E' ? 1 : (h == 'W' ? -1 : 0);
}

/* Hemisphere letter, then a body with its first '.' at `want` (the geo codecs' checks):
 * returns the text's length (spaces removed into t), -1 when Python rejects it; *sign, *dot set. */
static int geo_text(const tg_codec *c, const uint8_t *raw, size_t len, int want, uint8_t *t, int *sign, int *dot) {
    int n = squeeze(raw, len, t), k;
    *dot = -1;
    if (n < 0) return -1;
    *sign = n ? hemisphere(c, t[0]) : 0;
    if (!*sign) return -1;
    for (k = 1; k < n; k++)
        if (t[k] == '.') {
            *dot = k - 1;
            break;
        }
    return *dot == want ? n : -1;
}

static int dec_geodm(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    uint8_t t[MAX_TEXT];
    int sign, dot, k, f, n = geo_text(c, raw, len, c->lat ? 4 : 5, t, &sign, &dot);
    int64_t deg, minutes, num, q, r;
    if (n < 0) return TG_E_INVALID;
    for (k = 1; k < n; k++)
        if (k - 1 != dot && !is_digit(t[k])) return TG_E_INVALID;
    deg = digits_value(t + 1, (size_t)(dot - 2));
    f = n - 1 - dot - 1; /* minute fraction digits: 1..4 in a 10- or 11-character field */
    if (f < 1) return TG_E_INVALID;
    if (f > 4) return TG_E_UNSURE; /* wider than the catalog's fields: the tie argument needs f <= 4 */
    minutes = digits_value(t + 1 + dot - 2, 2) * POW10[f] + digits_value(t + 2 + dot, (size_t)f);
    if (minutes >= 60 * POW10[f]) return TG_E_INVALID;
    /* deg + minutes / (60 * 10^f), rounded to 7 decimals (never a tie: see docs/c.md) */
    num = minutes * POW10[7 - f];
    q = num / 60;
    r = num % 60;
    if (2 * r > 60 || (2 * r == 60 && (q & 1))) q++;
    num = deg * 10000000LL + q;
    /* beyond the limit: with at most 4 minute decimals, v > limit exactly when num > limit */
    if (num > (c->lat ? 90 : 180) * 10000000LL) return TG_E_INVALID;
    set_num(out, sign * num, -7);
    return TG_OK;
}

static int dec_geodeg(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    uint8_t t[MAX_TEXT];
    int sign, dot, k, r, n = geo_text(c, raw, len, c->lat ? 2 : 3, t, &sign, &dot);
    int64_t m;
    if (n < 0) return TG_E_INVALID;
    for (k = 1; k < n; k++)
        if (k - 1 != dot && !is_digit(t[k])) return TG_E_INVALID;
    if (n - 1 - dot - 1 < 1) return TG_E_INVALID; /* at least one decimal */
    r = parse_decimal(t + 1, (size_t)(n - 1), 7, &m);
    if (r != TG_OK) return TG_E_UNSURE;
    if (m > (c->lat ? 90 : 180) * 10000000LL) return TG_E_INVALID;
    set_num(out, sign * m, -7);
    return TG_OK;
}

static int days_in_month(unsigned y, unsigned m) {
    static const uint8_t d[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    if (m == 2 && ((y % 4 == 0 && y % 100 != 0) || y % 400 == 0)) return 29;
    return d[m - 1];
}

static int dec_timestamp(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    const char *l = c->text;
    size_t k = 0, i;
    tg_time t;
    int has_year = 0;
    memset(&t, 0, sizeof t);
    t.year = 1900;
    t.month = t.day = 1;
    for (i = 0; i < len; i++)
        if (raw[i] >= 0x80) return TG_E_INVALID;
    if (len != c->width) return TG_E_INVALID;
    while (*l) {
        if (*l == '%') {
            unsigned w = l[1] == 'Y' ? 4u : 2u;
            int64_t v;
            if (k + w > len || !all_digits(raw + k, w)) return TG_E_UNSURE;
            v = digits_value(raw + k, w);
            switch (l[1]) {
            case 'Y': t.year = (uint16_t)v; has_year = 1; break;
            case 'y': t.year = (uint16_t)(2000 + v); has_year = 1; break;
            case 'm': t.month = (uint8_t)v; break;
            case 'd': t.day = (uint8_t)v; break;
            case 'H': t.hour = (uint8_t)v; break;
            case 'M': t.minute = (uint8_t)v; break;
            case 'S': t.second = (uint8_t)v; break;
            case 'f': t.centis = (uint8_t)v; break;
            default: return TG_E_UNSURE;
            }
            k += w;
            l += l[1] == 'f' ? 3 : 2;
        } else {
            if (k >= len || raw[k] != (uint8_t)*l) return TG_E_UNSURE;
            k++;
            l++;
        }
    }
    (void)has_year;
    if (t.year < 1 || t.month < 1 || t.month > 12 || t.day < 1 || t.day > days_in_month(t.year, t.month) ||
        t.hour > 23 || t.minute > 59 || t.second > 59)
        return TG_E_UNSURE;
    clear(out, TG_V_TIME);
    out->time = t;
    return TG_OK;
}

int tg_codec_decode(const tg_codec *c, const uint8_t *raw, size_t len, tg_value *out) {
    static const uint8_t empty[1] = {0};
    if (len == 0) raw = empty; /* no bytes may come as a NULL pointer */
    switch (c->kind) {
    case TG_K_HEXINT: return dec_hexint(c, raw, len, out);
    case TG_K_DECINT: return dec_decint(c, raw, len, out);
    case TG_K_BININT: return dec_binint(c, raw, len, out);
    case TG_K_DECFLOAT: return dec_decfloat(c, raw, len, out);
    case TG_K_BITRATE: return dec_bitrate(c, raw, len, out);
    case TG_K_ENUM: return dec_enum(c, raw, len, out);
    case TG_K_ONEOF:
        if (dec_enum(c, raw, len, out) == TG_OK) return TG_OK;
        return tg_codec_decode(c->sub, raw, len, out);
    case TG_K_TEXT:
        if (len < c->min_width || len > c->max_width) return TG_E_INVALID;
        set_span(out, TG_V_TEXT, raw, len);
        return TG_OK;
    case TG_K_IPV4: {
        uint32_t a;
        size_t k;
        for (k = 0; k < len; k++)
            if (raw[k] >= 0x80) return TG_E_INVALID;
        if (parse_ipv4(raw, len, &a) != TG_OK) return TG_E_INVALID;
        set_span(out, TG_V_TEXT, raw, len);
        out->num = a;
        return TG_OK;
    }
    case TG_K_RAW:
        if (c->width && len != c->width) return TG_E_INVALID;
        set_span(out, TG_V_BYTES, raw, len);
        return TG_OK;
    case TG_K_LITERAL:
        if (!equals(raw, len, c->text)) return TG_E_INVALID;
        set_span(out, TG_V_TEXT, raw, len);
        return TG_OK;
    case TG_K_GEODM: return dec_geodm(c, raw, len, out);
    case TG_K_GEODEG: return dec_geodeg(c, raw, len, out);
    case TG_K_TIMESTAMP: return dec_timestamp(c, raw, len, out);
    default: return TG_E_UNSURE;
    }
}

/* ---- encoders ----------------------------------------------------------------------------- */

/* Decimal digits of v (>= 0), zero padded to at least `width`; returns count or TG_E_SPACE. */
static int put_uint(uint64_t v, unsigned width, uint8_t *out, size_t cap) {
    uint8_t tmp[24];
    unsigned n = 0, k;
    do {
        tmp[n++] = (uint8_t)('0' + v % 10);
        v /= 10;
    } while (v);
    while (n < width && n < sizeof tmp) tmp[n++] = '0';
    if (n > cap) return TG_E_SPACE;
    for (k = 0; k < n; k++) out[k] = tmp[n - 1 - k];
    return (int)n;
}

/* Python's f"{v:0{width}.{decimals}f}" for v = m * 10^-decimals. */
static int put_fixed(int64_t m, unsigned decimals, unsigned width, uint8_t *out, size_t cap) {
    uint8_t tmp[40];
    unsigned n = 0, k, digits;
    uint64_t a = m < 0 ? (uint64_t)(-(m + 1)) + 1 : (uint64_t)m;
    uint64_t ip = a / (uint64_t)POW10[decimals], fp = a % (uint64_t)POW10[decimals];
    int r;
    if (m < 0) tmp[n++] = '-';
    /* integer part, zero padded so the whole text is at least `width` characters */
    digits = 1;
    {
        uint64_t t = ip;
        while (t >= 10) {
            t /= 10;
            digits++;
        }
    }
    {
        unsigned body = n + digits + (decimals ? 1 + decimals : 0);
        unsigned zeros = width > body ? width - body : 0;
        r = put_uint(ip, digits + zeros, tmp + n, sizeof tmp - n);
        if (r < 0) return r;
        n += (unsigned)r;
    }
    if (decimals) {
        tmp[n++] = '.';
        r = put_uint(fp, decimals, tmp + n, sizeof tmp - n);
        if (r < 0) return r;
        n += (unsigned)r;
    }
    if (n > cap) return TG_E_SPACE;
    for (k = 0; k < n; k++) out[k] = tmp[k];
    return (int)n;
}

static int put_text(const char *s, uint8_t *out, size_t cap) {
    size_t n = strlen(s);
    if (n > cap) return TG_E_SPACE;
    memcpy(out, s, n);
    return (int)n;
}

/* A number rescaled to the codec's grid and checked against its range. */
static int grid_value(const tg_codec *c, const tg_value *v, int64_t *m) {
    int r;
    if (v->type != TG_V_NUM) return TG_E_TYPE;
    r = tg_value_rescale(v, c->exp10, m);
    if (r != TG_OK) return r;
    if (*m < c->lo || *m > c->hi) return TG_E_RANGE;
    return TG_OK;
}

static int enc_hexint(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m, raw;
    uint64_t u;
    unsigned k;
    int r;
    if (v->type == TG_V_NULL) return c->n_none ? put_text(c->none_tokens[0], out, cap) : TG_E_TYPE;
    r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    raw = c->mul == 1 ? m : div_round(m, c->mul);
    if (c->width < 16 && (raw >= ((int64_t)1 << (4 * c->width)) || raw < -((int64_t)1 << (4 * c->width))))
        return TG_E_RANGE;
    u = raw < 0 ? (uint64_t)(raw + ((int64_t)1 << (4 * c->width))) : (uint64_t)raw;
    if (c->width > cap) return TG_E_SPACE;
    for (k = 0; k < c->width; k++) out[c->width - 1 - k] = hexdigit((unsigned)((u >> (4 * k)) & 15));
    return c->width;
}

static int enc_decint(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m, raw;
    int r;
    r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    raw = c->mul == 1 ? m : div_round(m, c->mul);
    if (raw < 0) {
        if (cap < 1) return TG_E_SPACE;
        out[0] = '-';
        r = put_uint((uint64_t)-raw, c->width > 1 ? c->width - 1u : 0u, out + 1, cap - 1);
        return r < 0 ? r : r + 1;
    }
    return put_uint((uint64_t)raw, c->width, out, cap);
}

static int enc_binint(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m, raw;
    uint64_t u;
    unsigned k;
    int r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    raw = c->mul == 1 ? m : div_round(m, c->mul);
    u = (uint64_t)raw;
    if (c->width > cap) return TG_E_SPACE;
    for (k = 0; k < c->width; k++) out[c->little ? k : c->width - 1 - k] = (uint8_t)(u >> (8 * k));
    return c->width;
}

static int enc_decfloat(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m;
    int r;
    if (v->type == TG_V_NULL) return c->n_none ? put_text(c->none_tokens[0], out, cap) : TG_E_TYPE;
    r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    r = put_fixed(m, c->decimals, c->width ? c->width : c->pad, out, cap);
    if (r > 0 && c->width && (unsigned)r != c->width) return TG_E_RANGE;
    return r;
}

static int enc_bitrate(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t kbps;
    tg_value exact;
    if (v->type != TG_V_NUM) return TG_E_TYPE;
    if (tg_value_rescale(v, 0, &kbps) != TG_OK) return TG_E_RANGE;
    exact = *v;
    exact.num = kbps;
    exact.exp10 = 0;
    {
        int64_t back;
        if (tg_value_rescale(&exact, v->exp10, &back) != TG_OK || back != v->num) return TG_E_RANGE; /* whole kbps */
    }
    if (kbps < c->lo || kbps > c->hi) return TG_E_RANGE;
    if (cap < 6) return TG_E_SPACE;
    if (kbps % 1000 == 0 && kbps / 1000 >= 1 && kbps / 1000 <= 8) {
        out[0] = '0';
        out[1] = (uint8_t)('0' + kbps / 1000);
        out[2] = out[3] = out[4] = out[5] = '0';
        return 6;
    }
    out[0] = 'K';
    return put_uint((uint64_t)kbps, 5, out + 1, 5) < 0 ? TG_E_SPACE : 6;
}

static int enc_enum(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    if (v->type != TG_V_ENUM) return TG_E_TYPE;
    if (v->num < 0 || v->num >= c->n_values) return TG_E_RANGE;
    return put_text(c->raws[v->num], out, cap);
}

static int enc_span(const tg_value *v, uint8_t *out, size_t cap) {
    if (v->len > cap) return TG_E_SPACE;
    if (v->len) memcpy(out, v->ptr, v->len);
    return v->len;
}

static int enc_text(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    unsigned k;
    if (v->type != TG_V_TEXT) return TG_E_TYPE;
    if (v->len < c->min_width || v->len > c->max_width) return TG_E_RANGE;
    for (k = 0; k < v->len; k++) /* printable ASCII without '#': no frame can be injected */
        if (v->ptr[k] < 0x20 || v->ptr[k] >= 0x7F || v->ptr[k] == '#') return TG_E_RANGE;
    return enc_span(v, out, cap);
}

static int enc_raw(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    unsigned k;
    if (v->type != TG_V_BYTES) return TG_E_TYPE;
    if (v->len < c->min_width || v->len > c->max_width) return TG_E_RANGE;
    if (!c->binary) /* '#', CR, LF would split the frame on a stream */
        for (k = 0; k < v->len; k++)
            if (v->ptr[k] == '#' || v->ptr[k] == '\r' || v->ptr[k] == '\n') return TG_E_RANGE;
    return enc_span(v, out, cap);
}

static int enc_ipv4(const tg_value *v, uint8_t *out, size_t cap) {
    uint32_t a;
    int k, n = 0, r;
    if (v->type == TG_V_TEXT) {
        if (parse_ipv4(v->ptr, v->len, &a) != TG_OK) return TG_E_RANGE;
        return enc_span(v, out, cap);
    }
    if (v->type != TG_V_NUM || v->exp10 != 0 || v->num < 0 || v->num > 0xFFFFFFFFLL) return TG_E_TYPE;
    a = (uint32_t)v->num;
    for (k = 3; k >= 0; k--) {
        r = put_uint((a >> (8 * k)) & 0xFF, 1, out + n, cap - (size_t)n);
        if (r < 0) return r;
        n += r;
        if (k) {
            if ((size_t)n >= cap) return TG_E_SPACE;
            out[n++] = '.';
        }
    }
    return n;
}

static uint8_t hemisphere_letter(const tg_codec *c, int negative) {
    return (uint8_t)(c->lat ? (negative ? 'S' : 'N') : (negative ? 'W' : 'E'));
}

static int enc_geodm(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m, a, deg, frac, mins;
    int n = 0, r;
    r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    if (cap < c->width) return TG_E_SPACE;
    a = m < 0 ? -m : m;
    deg = a / 10000000LL;
    frac = a % 10000000LL;
    mins = div_round(frac * 3, 50); /* minutes * 10^4 = frac * 60 / 1000 */
    if (mins >= 600000) {
        deg++;
        mins = 0;
    }
    out[n++] = hemisphere_letter(c, m < 0 && (deg || mins)); /* what rounds to 0 is N / E */
    r = put_uint((uint64_t)deg, c->lat ? 2u : 3u, out + n, cap - (size_t)n);
    if (r < 0) return r;
    n += r;
    r = put_fixed(mins, 4, 7, out + n, cap - (size_t)n);
    if (r < 0) return r;
    return n + r;
}

static int enc_geodeg(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    int64_t m;
    int r;
    r = grid_value(c, v, &m);
    if (r != TG_OK) return r;
    if (cap < 1) return TG_E_SPACE;
    {
        tg_value deg6 = *v;
        int64_t d6;
        deg6.num = m < 0 ? -m : m;
        deg6.exp10 = -7;
        if (tg_value_rescale(&deg6, -6, &d6) != TG_OK) return TG_E_RANGE;
        out[0] = hemisphere_letter(c, m < 0 && d6);
        r = put_fixed(d6, 6, c->width - 1u, out + 1, cap - 1);
    }
    return r < 0 ? r : r + 1;
}

static int enc_timestamp(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    const char *l = c->text;
    const tg_time *t = &v->time;
    size_t n = 0;
    if (v->type != TG_V_TIME) return TG_E_TYPE;
    if (t->month < 1 || t->month > 12 || t->day < 1 || t->day > days_in_month(t->year, t->month) || t->hour > 23 ||
        t->minute > 59 || t->second > 59 || t->centis > 99 || t->year < 1 || t->year > 9999)
        return TG_E_RANGE;
    if (cap < c->width) return TG_E_SPACE;
    while (*l) {
        if (*l == '%') {
            unsigned val, w = 2;
            switch (l[1]) {
            case 'Y': val = t->year; w = 4; break;
            case 'y':
                if (t->year < 2000 || t->year > 2099) return TG_E_RANGE;
                val = t->year % 100u;
                break;
            case 'm': val = t->month; break;
            case 'd': val = t->day; break;
            case 'H': val = t->hour; break;
            case 'M': val = t->minute; break;
            case 'S': val = t->second; break;
            case 'f': val = t->centis; break;
            default: return TG_E_ARG;
            }
            if (put_uint(val, w, out + n, cap - n) != (int)w) return TG_E_RANGE;
            n += w;
            l += l[1] == 'f' ? 3 : 2;
        } else {
            out[n++] = (uint8_t)*l++;
        }
    }
    return (int)n;
}

int tg_codec_encode(const tg_codec *c, const tg_value *v, uint8_t *out, size_t cap) {
    uint8_t nowhere; /* out may be NULL when cap is 0: `out + n` then points here (never written) */
    if (!out) {
        out = &nowhere;
        cap = 0;
    }
    switch (c->kind) {
    case TG_K_HEXINT: return enc_hexint(c, v, out, cap);
    case TG_K_DECINT: return enc_decint(c, v, out, cap);
    case TG_K_BININT: return enc_binint(c, v, out, cap);
    case TG_K_DECFLOAT: return enc_decfloat(c, v, out, cap);
    case TG_K_BITRATE: return enc_bitrate(c, v, out, cap);
    case TG_K_ENUM: return enc_enum(c, v, out, cap);
    case TG_K_ONEOF: return v->type == TG_V_ENUM ? enc_enum(c, v, out, cap) : tg_codec_encode(c->sub, v, out, cap);
    case TG_K_TEXT: return enc_text(c, v, out, cap);
    case TG_K_IPV4: return enc_ipv4(v, out, cap);
    case TG_K_RAW: return enc_raw(c, v, out, cap);
    case TG_K_LITERAL:
        if (v->type == TG_V_TEXT && !equals(v->ptr, v->len, c->text)) return TG_E_RANGE;
        if (v->type != TG_V_TEXT && v->type != TG_V_NULL && v->type != TG_V_ABSENT) return TG_E_TYPE;
        return put_text(c->text, out, cap);
    case TG_K_GEODM: return enc_geodm(c, v, out, cap);
    case TG_K_GEODEG: return enc_geodeg(c, v, out, cap);
    case TG_K_TIMESTAMP: return enc_timestamp(c, v, out, cap);
    default: return TG_E_ARG;
    }
}
