/*
 * topgimbal._speedups._ctop: the Python fast path, built from libtopgimbal's own sources
 * (c/src/tg_scan.c, c/src/tg_codec.c).
 *
 * scan():    one call of FrameParser._scan over a bytes buffer; good frames come back as Frame
 *            objects, everything rare (diagnostics, recovered frames) as small tuples that the
 *            Python wrapper turns into exactly what the pure parser produces.
 * Decoder:   Dialect.decode for the forms the C codecs handle natively; fields of other codecs go
 *            to their Python codec, and any frame the C core is not sure about goes to the pure
 *            decoder whole, so results are identical to the pure path by construction.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "topgimbal.h"

#define ABI_VERSION 1

static PyObject *headers[5]; /* "#TP" ... by tg_header code */

static PyObject *new_tuple_of(PyTypeObject *cls, Py_ssize_t n) {
    /* A NamedTuple instance is a plain tuple of its type: what tuple.__new__(cls, items) builds. */
    return cls->tp_alloc(cls, n);
}

static PyObject *make_frame(PyTypeObject *frame_cls, const uint8_t *buf, const tg_step *st) {
    tg_frame f;
    PyObject *obj, *ident, *data, *rw;
    tg_step_frame(buf, st, &f);
    ident = PyUnicode_DecodeLatin1(f.ident, 3, NULL);
    data = PyBytes_FromStringAndSize((const char *)f.data, f.len);
    rw = f.rw ? PyUnicode_FromOrdinal((unsigned char)f.rw) : PyUnicode_FromStringAndSize("", 0);
    obj = new_tuple_of(frame_cls, 7);
    if (!ident || !data || !rw || !obj) {
        Py_XDECREF(ident);
        Py_XDECREF(data);
        Py_XDECREF(rw);
        Py_XDECREF(obj);
        return NULL;
    }
    Py_INCREF(headers[f.header]);
    PyTuple_SET_ITEM(obj, 0, headers[f.header]);
    PyTuple_SET_ITEM(obj, 1, PyUnicode_FromOrdinal((unsigned char)f.src));
    PyTuple_SET_ITEM(obj, 2, PyUnicode_FromOrdinal((unsigned char)f.dst));
    PyTuple_SET_ITEM(obj, 3, rw);
    PyTuple_SET_ITEM(obj, 4, ident);
    PyTuple_SET_ITEM(obj, 5, data);
    if (f.declared >= 0) {
        PyTuple_SET_ITEM(obj, 6, PyLong_FromLong(f.declared));
    } else {
        Py_INCREF(Py_None);
        PyTuple_SET_ITEM(obj, 6, Py_None);
    }
    if (!PyTuple_GET_ITEM(obj, 1) || !PyTuple_GET_ITEM(obj, 2) || !PyTuple_GET_ITEM(obj, 6)) {
        Py_DECREF(obj);
        return NULL;
    }
    return obj;
}

static const char *diag_name(uint8_t diag) {
    switch (diag) {
    case TG_DIAG_GARBAGE: return "garbage";
    case TG_DIAG_BAD_HEADER: return "bad_header";
    case TG_DIAG_BAD_LENGTH: return "bad_length";
    case TG_DIAG_OVERSIZE: return "oversize";
    case TG_DIAG_BAD_CHECKSUM: return "bad_checksum";
    default: return "length_mismatch";
    }
}

/* scan(buf, pos, final, max_data, recover, flags, frame_cls) -> (pos, items, nframes) */
static PyObject *ctop_scan(PyObject *self, PyObject *args) {
    Py_buffer view;
    Py_ssize_t pos, max_data;
    int final, recover, flags;
    PyObject *frame_cls, *items, *item;
    tg_scan_cfg cfg;
    tg_step st;
    Py_ssize_t nframes = 0;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*npnpiO", &view, &pos, &final, &max_data, &recover, &flags, &frame_cls)) return NULL;
    if (!PyType_Check(frame_cls) || !PyType_IsSubtype((PyTypeObject *)frame_cls, &PyTuple_Type)) {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_TypeError, "frame_cls must be a tuple subclass (Frame)");
        return NULL;
    }
    cfg.max_data = max_data < 0 ? 0 : (max_data > 0xFFFF ? 0xFFFF : (uint32_t)max_data);
    cfg.recover_length = (uint8_t)recover;
    cfg.flags = (uint8_t)flags;
    items = PyList_New(0);
    if (!items) {
        PyBuffer_Release(&view);
        return NULL;
    }
    for (;;) {
        const uint8_t *buf = (const uint8_t *)view.buf;
        tg_scan_step(buf, (size_t)view.len, (size_t)pos, final, &cfg, &st);
        item = NULL;
        switch (st.kind) {
        case TG_STEP_WAIT: {
            PyObject *r = Py_BuildValue("(nNn)", (Py_ssize_t)st.next, items, nframes);
            PyBuffer_Release(&view);
            return r;
        }
        case TG_STEP_FRAME:
            item = make_frame((PyTypeObject *)frame_cls, buf, &st);
            nframes++;
            break;
        case TG_STEP_RECOVERED: {
            PyObject *fr = make_frame((PyTypeObject *)frame_cls, buf, &st);
            if (fr) item = Py_BuildValue("(snnN)", "R", (Py_ssize_t)st.start, (Py_ssize_t)st.end, fr);
            break;
        }
        case TG_STEP_BAD_CHECKSUM:
            item = Py_BuildValue("(snnn)", "C", (Py_ssize_t)st.start, (Py_ssize_t)st.end, (Py_ssize_t)st.next);
            break;
        default:
            item = Py_BuildValue("(snnsi)", "D", (Py_ssize_t)st.start, (Py_ssize_t)st.end, diag_name(st.diag),
                                 (int)st.reason);
        }
        if (!item || PyList_Append(items, item) < 0) {
            Py_XDECREF(item);
            Py_DECREF(items);
            PyBuffer_Release(&view);
            return NULL;
        }
        Py_DECREF(item);
        pos = (Py_ssize_t)st.next;
        if (st.kind == TG_STEP_DISCARD && st.next >= (size_t)view.len) {
            PyObject *r = Py_BuildValue("(nNn)", (Py_ssize_t)st.next, items, nframes);
            PyBuffer_Release(&view);
            return r;
        }
    }
}

/* ---- decoder ------------------------------------------------------------------------------ */

typedef struct {
    PyObject *name;     /* field name (str) */
    PyObject *pycodec;  /* the Python codec, when this field is delegated to it */
    PyObject *names;    /* enum value names (tuple of str), or NULL */
    PyObject *literal;  /* literal text (str), or NULL */
    tg_codec *codec;    /* native codec, NULL when delegated */
    Py_ssize_t offset, width; /* width 0: the rest of the data */
} dfield;

typedef struct {
    PyObject *form;      /* the catalog Form */
    PyObject *const_data; /* bytes or NULL */
    Py_ssize_t min_len, max_len, n_fields;
    dfield *fields;
} dform;

typedef struct {
    uint32_t key;       /* 3 identifier bytes, 0 = empty slot */
    PyObject *spec;
    Py_ssize_t n_forms;
    dform *forms;
    uint8_t *order[2][2];
    Py_ssize_t n_order[2][2];
} dcommand;

typedef struct {
    PyObject_HEAD
    PyObject *message_cls;
    PyObject *fallback;
    PyObject *keep;        /* objects whose memory the tables point into */
    Py_ssize_t n_slots;    /* power of two */
    dcommand *slots;
} Decoder;

static uint32_t ident_key(const unsigned char *p) { return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16); }

static uint32_t slot_of(uint32_t key, Py_ssize_t n_slots) { return ((key * 2654435761u) >> 16) & (uint32_t)(n_slots - 1); }

static void free_codec(tg_codec *c) {
    if (!c) return;
    PyMem_Free((void *)c->raws);
    PyMem_Free((void *)c->spellings);
    PyMem_Free((void *)c->none_tokens);
    free_codec((tg_codec *)c->sub);
    PyMem_Free(c);
}

static void Decoder_dealloc(Decoder *self) {
    Py_ssize_t s, f, k;
    int a, b;
    if (self->slots) {
        for (s = 0; s < self->n_slots; s++) {
            dcommand *c = &self->slots[s];
            if (!c->key) continue;
            for (f = 0; f < c->n_forms; f++) {
                for (k = 0; k < c->forms[f].n_fields; k++) free_codec(c->forms[f].fields[k].codec);
                PyMem_Free(c->forms[f].fields);
            }
            PyMem_Free(c->forms);
            for (a = 0; a < 2; a++)
                for (b = 0; b < 2; b++) PyMem_Free(c->order[a][b]);
        }
        PyMem_Free(self->slots);
    }
    Py_XDECREF(self->message_cls);
    Py_XDECREF(self->fallback);
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* Keep `obj` alive for the decoder's lifetime; returns it (borrowed). */
static PyObject *keep(Decoder *d, PyObject *obj) {
    if (!obj || PyList_Append(d->keep, obj) < 0) return NULL;
    return obj;
}

static const char *bytes_str(Decoder *d, PyObject *b) {
    if (!PyBytes_Check(b) || !keep(d, b)) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "expected bytes");
        return NULL;
    }
    return PyBytes_AS_STRING(b); /* NUL-terminated */
}

/* A codec descriptor tuple from speedups.py (see _codec_tuple there) -> tg_codec. */
static tg_codec *build_codec(Decoder *d, PyObject *t) {
    tg_codec *c;
    PyObject *raws, *spell, *nones, *text, *sub;
    int kind, width, minw, maxw, sgn, little, lat, pyfloat, exp10, decimals, pad;
    long mul;
    long long lo, hi;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(t, "iiiiiiiiiiilLLOOOOO", &kind, &width, &minw, &maxw, &sgn, &little, &lat, &pyfloat,
                          &exp10, &decimals, &pad, &mul, &lo, &hi, &raws, &spell, &nones, &text, &sub))
        return NULL;
    c = PyMem_Calloc(1, sizeof *c);
    if (!c) return (tg_codec *)PyErr_NoMemory();
    c->kind = (uint8_t)kind;
    c->width = (uint8_t)width;
    c->min_width = (uint8_t)minw;
    c->max_width = (uint8_t)maxw;
    c->is_signed = (uint8_t)sgn;
    c->little = (uint8_t)little;
    c->lat = (uint8_t)lat;
    c->pyfloat = (uint8_t)pyfloat;
    c->exp10 = (int8_t)exp10;
    c->decimals = (uint8_t)decimals;
    c->pad = (uint8_t)pad;
    c->mul = (int32_t)mul;
    c->lo = lo;
    c->hi = hi;
    if (!PyTuple_Check(raws) || !PyTuple_Check(spell) || !PyTuple_Check(nones)) goto bad;
    c->n_values = (uint8_t)PyTuple_GET_SIZE(raws);
    c->n_spellings = (uint8_t)PyTuple_GET_SIZE(spell);
    c->n_none = (uint8_t)PyTuple_GET_SIZE(nones);
    if (c->n_values) {
        const char **r = PyMem_Calloc((size_t)c->n_values, sizeof *r);
        if (!(c->raws = r)) goto bad;
        for (k = 0; k < c->n_values; k++)
            if (!(r[k] = bytes_str(d, PyTuple_GET_ITEM(raws, k)))) goto bad;
    }
    if (c->n_spellings) {
        tg_spelling *s = PyMem_Calloc((size_t)c->n_spellings, sizeof *s);
        if (!(c->spellings = s)) goto bad;
        for (k = 0; k < c->n_spellings; k++) {
            PyObject *pair = PyTuple_GET_ITEM(spell, k);
            if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2) goto bad;
            if (!(s[k].raw = bytes_str(d, PyTuple_GET_ITEM(pair, 0)))) goto bad;
            s[k].value = (uint8_t)PyLong_AsLong(PyTuple_GET_ITEM(pair, 1));
        }
    }
    if (c->n_none) {
        const char **n = PyMem_Calloc((size_t)c->n_none, sizeof *n);
        if (!(c->none_tokens = n)) goto bad;
        for (k = 0; k < c->n_none; k++)
            if (!(n[k] = bytes_str(d, PyTuple_GET_ITEM(nones, k)))) goto bad;
    }
    if (PyBytes_Check(text) && PyBytes_GET_SIZE(text) && !(c->text = bytes_str(d, text))) goto bad;
    if (sub != Py_None && !(c->sub = build_codec(d, sub))) goto bad;
    return c;
bad:
    free_codec(c);
    if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "bad codec descriptor");
    return NULL;
}

static int build_form(Decoder *d, PyObject *t, dform *f) {
    PyObject *fields;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(t, "OOnnO", &f->form, &f->const_data, &f->min_len, &f->max_len, &fields)) return -1;
    if (!keep(d, f->form)) return -1;
    if (f->const_data == Py_None) {
        f->const_data = NULL;
    } else if (!PyBytes_Check(f->const_data) || !keep(d, f->const_data)) {
        PyErr_SetString(PyExc_TypeError, "const data must be bytes or None");
        return -1;
    }
    if (!PyTuple_Check(fields)) return PyErr_SetString(PyExc_TypeError, "fields must be a tuple"), -1;
    f->n_fields = PyTuple_GET_SIZE(fields);
    f->fields = PyMem_Calloc((size_t)(f->n_fields ? f->n_fields : 1), sizeof *f->fields);
    if (!f->fields) return PyErr_NoMemory(), -1;
    for (k = 0; k < f->n_fields; k++) {
        dfield *x = &f->fields[k];
        PyObject *desc, *names, *literal;
        if (!PyArg_ParseTuple(PyTuple_GET_ITEM(fields, k), "OnnOOOO", &x->name, &x->offset, &x->width, &desc,
                              &x->pycodec, &names, &literal))
            return -1;
        if (!keep(d, x->name) || !keep(d, x->pycodec)) return -1;
        x->names = names == Py_None ? NULL : keep(d, names);
        x->literal = literal == Py_None ? NULL : keep(d, literal);
        if (desc != Py_None && !(x->codec = build_codec(d, desc))) return -1;
    }
    return 0;
}

static int build_command(Decoder *d, PyObject *t, dcommand *c) {
    PyObject *ident, *forms, *orders;
    Py_ssize_t k;
    int a, b;
    if (!PyArg_ParseTuple(t, "OOOO", &ident, &c->spec, &forms, &orders)) return -1;
    if (!PyBytes_Check(ident) || PyBytes_GET_SIZE(ident) != 3)
        return PyErr_SetString(PyExc_ValueError, "identifier must be 3 bytes"), -1;
    if (!keep(d, c->spec)) return -1;
    c->key = ident_key((const unsigned char *)PyBytes_AS_STRING(ident));
    c->n_forms = PyTuple_GET_SIZE(forms);
    c->forms = PyMem_Calloc((size_t)(c->n_forms ? c->n_forms : 1), sizeof *c->forms);
    if (!c->forms) return PyErr_NoMemory(), -1;
    for (k = 0; k < c->n_forms; k++)
        if (build_form(d, PyTuple_GET_ITEM(forms, k), &c->forms[k]) < 0) return -1;
    for (a = 0; a < 2; a++)
        for (b = 0; b < 2; b++) {
            PyObject *o = PyTuple_GET_ITEM(PyTuple_GET_ITEM(orders, a), b);
            Py_ssize_t n = PyTuple_GET_SIZE(o), i;
            c->n_order[a][b] = n;
            c->order[a][b] = PyMem_Calloc((size_t)(n ? n : 1), 1);
            if (!c->order[a][b]) return PyErr_NoMemory(), -1;
            for (i = 0; i < n; i++) c->order[a][b][i] = (uint8_t)PyLong_AsLong(PyTuple_GET_ITEM(o, i));
        }
    return 0;
}

/* Decoder(commands, message_cls, fallback); commands: tuple of
 * (ident bytes, spec, forms, ((r_req, r_rsp), (w_req, w_rsp))) */
static int Decoder_init(Decoder *self, PyObject *args, PyObject *kw) {
    PyObject *commands;
    Py_ssize_t n, k;
    (void)kw;
    if (!PyArg_ParseTuple(args, "O!OO", &PyTuple_Type, &commands, &self->message_cls, &self->fallback)) return -1;
    Py_INCREF(self->message_cls);
    Py_INCREF(self->fallback);
    if (!PyType_Check(self->message_cls) ||
        !PyType_IsSubtype((PyTypeObject *)self->message_cls, &PyTuple_Type))
        return PyErr_SetString(PyExc_TypeError, "message_cls must be a tuple subclass"), -1;
    self->keep = PyList_New(0);
    if (!self->keep) return -1;
    n = PyTuple_GET_SIZE(commands);
    self->n_slots = 8;
    while (self->n_slots < 2 * n) self->n_slots *= 2;
    self->slots = PyMem_Calloc((size_t)self->n_slots, sizeof *self->slots);
    if (!self->slots) return PyErr_NoMemory(), -1;
    for (k = 0; k < n; k++) {
        dcommand tmp;
        uint32_t s;
        memset(&tmp, 0, sizeof tmp);
        if (build_command(self, PyTuple_GET_ITEM(commands, k), &tmp) < 0) {
            /* free what the half-built command owns */
            Py_ssize_t f, j;
            int a, b;
            for (f = 0; f < tmp.n_forms && tmp.forms; f++) {
                if (tmp.forms[f].fields)
                    for (j = 0; j < tmp.forms[f].n_fields; j++) free_codec(tmp.forms[f].fields[j].codec);
                PyMem_Free(tmp.forms[f].fields);
            }
            PyMem_Free(tmp.forms);
            for (a = 0; a < 2; a++)
                for (b = 0; b < 2; b++) PyMem_Free(tmp.order[a][b]);
            return -1;
        }
        s = slot_of(tmp.key, self->n_slots);
        while (self->slots[s].key) s = (s + 1) & (uint32_t)(self->n_slots - 1);
        self->slots[s] = tmp;
    }
    return 0;
}

static const dcommand *lookup(const Decoder *d, uint32_t key) {
    uint32_t s = slot_of(key, d->n_slots);
    while (d->slots[s].key) {
        if (d->slots[s].key == key) return &d->slots[s];
        s = (s + 1) & (uint32_t)(d->n_slots - 1);
    }
    return NULL;
}

static const double POW10D[10] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};

static PyObject *hex_str(const uint8_t *p, Py_ssize_t n) {
    static const char digits[] = "0123456789abcdef";
    PyObject *s = PyUnicode_New(2 * n, 127);
    Py_UCS1 *out;
    Py_ssize_t k;
    if (!s) return NULL;
    out = PyUnicode_1BYTE_DATA(s);
    for (k = 0; k < n; k++) {
        out[2 * k] = (Py_UCS1)digits[p[k] >> 4];
        out[2 * k + 1] = (Py_UCS1)digits[p[k] & 15];
    }
    return s;
}

/* The Python value of a natively decoded field (new reference). */
static PyObject *py_value(const dfield *f, const tg_codec *c, const tg_value *v) {
    switch (v->type) {
    case TG_V_NULL: Py_RETURN_NONE;
    case TG_V_ENUM: {
        PyObject *name = PyTuple_GET_ITEM(f->names, v->num);
        Py_INCREF(name);
        return name;
    }
    case TG_V_NUM: {
        int pyfloat = c->pyfloat;
        if (c->kind == TG_K_ONEOF && c->sub) pyfloat = c->sub->pyfloat;
        if (!pyfloat) return PyLong_FromLongLong(v->num);
        if (v->exp10 < 0) return PyFloat_FromDouble((double)v->num / POW10D[-v->exp10]);
        return PyFloat_FromDouble((double)v->num * POW10D[v->exp10]);
    }
    case TG_V_TEXT:
        if (f->literal) {
            Py_INCREF(f->literal);
            return f->literal;
        }
        return PyUnicode_DecodeLatin1((const char *)v->ptr, v->len, NULL);
    case TG_V_BYTES: return hex_str(v->ptr, v->len);
    default: PyErr_SetString(PyExc_RuntimeError, "unexpected value type"); return NULL;
    }
}

enum { FORM_OK = 0, FORM_FAIL = 1, FORM_UNSURE = 2, FORM_ERROR = -1 };

static int decode_form(const dform *form, const uint8_t *data, Py_ssize_t len, PyObject *data_obj, PyObject **out) {
    PyObject *dict;
    Py_ssize_t k;
    if (form->const_data) {
        if (len != PyBytes_GET_SIZE(form->const_data) || memcmp(data, PyBytes_AS_STRING(form->const_data), (size_t)len))
            return FORM_FAIL;
        *out = PyDict_New();
        return *out ? FORM_OK : FORM_ERROR;
    }
    dict = PyDict_New();
    if (!dict) return FORM_ERROR;
    for (k = 0; k < form->n_fields; k++) {
        const dfield *f = &form->fields[k];
        Py_ssize_t w = f->width ? f->width : len - f->offset;
        PyObject *value;
        if (f->codec) {
            tg_value v;
            int r = tg_codec_decode(f->codec, data + f->offset, (size_t)w, &v);
            if (r != TG_OK) {
                Py_DECREF(dict);
                return r == TG_E_INVALID ? FORM_FAIL : FORM_UNSURE;
            }
            value = py_value(f, f->codec, &v);
        } else {
            PyObject *slice = (f->offset == 0 && w == len) ? (Py_INCREF(data_obj), data_obj)
                                                            : PyBytes_FromStringAndSize((const char *)data + f->offset, w);
            if (!slice) {
                Py_DECREF(dict);
                return FORM_ERROR;
            }
            value = PyObject_CallMethod(f->pycodec, "decode", "O", slice);
            Py_DECREF(slice);
            if (!value && (PyErr_ExceptionMatches(PyExc_ValueError) || PyErr_ExceptionMatches(PyExc_UnicodeDecodeError))) {
                PyErr_Clear();
                Py_DECREF(dict);
                return FORM_FAIL;
            }
        }
        if (!value || PyDict_SetItem(dict, f->name, value) < 0) {
            Py_XDECREF(value);
            Py_DECREF(dict);
            return FORM_ERROR;
        }
        Py_DECREF(value);
    }
    *out = dict;
    return FORM_OK;
}

static int is_device(Py_UCS4 a) { return a == 'M' || a == 'D' || a == 'E' || a == 'G'; }
static int is_host(Py_UCS4 a) { return a == 'U' || a == 'P'; }

static Py_UCS4 one_char(PyObject *s) {
    if (!PyUnicode_Check(s) || PyUnicode_GET_LENGTH(s) != 1) return 0;
    return PyUnicode_READ_CHAR(s, 0);
}

static PyObject *message(Decoder *self, PyObject *frame, PyObject *spec, PyObject *form, PyObject *fields,
                         PyObject *error) {
    PyObject *msg = new_tuple_of((PyTypeObject *)self->message_cls, 5);
    if (!msg) {
        Py_XDECREF(fields);
        Py_XDECREF(error);
        return NULL;
    }
    Py_INCREF(frame);
    Py_INCREF(spec);
    Py_INCREF(form);
    if (!fields) fields = (Py_INCREF(Py_None), Py_None);
    if (!error) error = (Py_INCREF(Py_None), Py_None);
    PyTuple_SET_ITEM(msg, 0, frame);
    PyTuple_SET_ITEM(msg, 1, spec);
    PyTuple_SET_ITEM(msg, 2, form);
    PyTuple_SET_ITEM(msg, 3, fields);
    PyTuple_SET_ITEM(msg, 4, error);
    return msg;
}

/* Dialect.decode's words when no form takes the data's length (the common failure: a frame
 * given to the other dialect); NULL with no exception set when another wording applies. */
static PyObject *length_error(const dcommand *c, int w, int dir, Py_ssize_t len, const char *ident) {
    PyObject *parts = PyList_New(0), *sep, *joined, *err;
    Py_ssize_t k;
    if (!parts) return NULL;
    for (k = 0; k < c->n_order[w][dir]; k++) {
        const dform *f = &c->forms[c->order[w][dir][k]];
        PyObject *t = f->max_len != f->min_len ? PyUnicode_FromFormat("%zd..%zd", f->min_len, f->max_len)
                                               : PyUnicode_FromFormat("%zd", f->min_len);
        if (!t || PyList_Append(parts, t) < 0) {
            Py_XDECREF(t);
            Py_DECREF(parts);
            return NULL;
        }
        Py_DECREF(t);
    }
    sep = PyUnicode_FromString(" or ");
    joined = sep ? PyUnicode_Join(sep, parts) : NULL;
    Py_XDECREF(sep);
    Py_DECREF(parts);
    if (!joined) return NULL;
    err = PyUnicode_FromFormat("%zd data bytes; %.3s (%c) takes %U", len, ident, w ? 'w' : 'r', joined);
    Py_DECREF(joined);
    return err;
}

static PyObject *decode_one(Decoder *self, PyObject *frame) {
    PyObject *ident, *data, *rw, *fields = NULL;
    const dcommand *c;
    const uint8_t *ip;
    int w, dir, last_was_length = 0;
    Py_ssize_t k, len;
    if (!PyTuple_Check(frame) || PyTuple_GET_SIZE(frame) < 6) goto fallback;
    ident = PyTuple_GET_ITEM(frame, 4);
    data = PyTuple_GET_ITEM(frame, 5);
    rw = PyTuple_GET_ITEM(frame, 3);
    if (!PyUnicode_Check(ident) || PyUnicode_GET_LENGTH(ident) != 3 || PyUnicode_KIND(ident) != PyUnicode_1BYTE_KIND ||
        !PyBytes_Check(data) || !PyUnicode_Check(rw))
        goto fallback;
    ip = PyUnicode_1BYTE_DATA(ident);
    c = lookup(self, ident_key(ip));
    if (!c) goto fallback;
    dir = is_device(one_char(PyTuple_GET_ITEM(frame, 1))) && is_host(one_char(PyTuple_GET_ITEM(frame, 2)));
    w = one_char(rw) != 'r';
    len = PyBytes_GET_SIZE(data);
    for (k = 0; k < c->n_order[w][dir]; k++) {
        const dform *form = &c->forms[c->order[w][dir][k]];
        int r;
        if (len < form->min_len || len > form->max_len) {
            last_was_length = 1;
            continue;
        }
        last_was_length = 0;
        r = decode_form(form, (const uint8_t *)PyBytes_AS_STRING(data), len, data, &fields);
        if (r == FORM_ERROR) return NULL;
        if (r == FORM_UNSURE) goto fallback;
        if (r == FORM_OK) return message(self, frame, c->spec, form->form, fields, NULL);
    }
    if (last_was_length) {
        PyObject *err = length_error(c, w, dir, len, (const char *)ip);
        if (!err) return NULL;
        return message(self, frame, c->spec, Py_None, NULL, err);
    }
fallback:
    /* Unknown identifier, no form fits (the pure decoder words the error), or a spelling only
     * Python reads: the pure decoder answers. */
    return PyObject_CallOneArg(self->fallback, frame);
}

static PyObject *Decoder_call(Decoder *self, PyObject *args, PyObject *kw) {
    PyObject *frame;
    (void)kw;
    if (!PyArg_ParseTuple(args, "O", &frame)) return NULL;
    return decode_one(self, frame);
}

static PyObject *Decoder_decode_many(Decoder *self, PyObject *frames) {
    PyObject *seq = PySequence_Fast(frames, "frames must be a sequence"), *out;
    Py_ssize_t n, k;
    if (!seq) return NULL;
    n = PySequence_Fast_GET_SIZE(seq);
    out = PyList_New(n);
    if (!out) {
        Py_DECREF(seq);
        return NULL;
    }
    for (k = 0; k < n; k++) {
        PyObject *m = decode_one(self, PySequence_Fast_GET_ITEM(seq, k));
        if (!m) {
            Py_DECREF(out);
            Py_DECREF(seq);
            return NULL;
        }
        PyList_SET_ITEM(out, k, m);
    }
    Py_DECREF(seq);
    return out;
}

static PyMethodDef Decoder_methods[] = {
    {"decode_many", (PyCFunction)Decoder_decode_many, METH_O, "Decode a sequence of frames -> list of Message."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject DecoderType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "topgimbal._speedups._ctop.Decoder",
    .tp_basicsize = sizeof(Decoder),
    .tp_dealloc = (destructor)Decoder_dealloc,
    .tp_call = (ternaryfunc)Decoder_call,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Decoder(commands, message_cls, fallback): Dialect.decode in C (see speedups.py).",
    .tp_methods = Decoder_methods,
    .tp_init = (initproc)Decoder_init,
    .tp_new = PyType_GenericNew,
};

static PyMethodDef methods[] = {
    {"scan", ctop_scan, METH_VARARGS, "scan(buf, pos, final, max_data, recover, flags, frame_cls) -> (pos, items, nframes)"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_ctop", "libtopgimbal fast path", -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__ctop(void) {
    PyObject *m;
    static const char *const texts[5] = {"", "#TP", "#tp", "#tP", "#Tp"};
    int k;
    if (PyType_Ready(&DecoderType) < 0) return NULL;
    for (k = 0; k < 5; k++)
        if (!headers[k] && !(headers[k] = PyUnicode_InternFromString(texts[k]))) return NULL;
    m = PyModule_Create(&module);
    if (!m) return NULL;
    Py_INCREF(&DecoderType);
    if (PyModule_AddObject(m, "Decoder", (PyObject *)&DecoderType) < 0 ||
        PyModule_AddIntConstant(m, "ABI_VERSION", ABI_VERSION) < 0 ||
        PyModule_AddIntConstant(m, "SCAN_DEFAULT", TG_SCAN_DEFAULT) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
