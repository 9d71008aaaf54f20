-- ---------------------------------------------------------------------------------------------
-- Runtime (fixed; the tables above are generated). Lua 5.2 as embedded in Wireshark >= 3.x.
--
-- Frame scanning follows topgimbal's FrameParser rule for rule (resync at the next '#', a good
-- frame never held back by garbage, length recovery when the checksum proves the real length),
-- and field decoding follows each codec class of the catalog, so Wireshark shows what
-- `topgimbal decode` shows. Offsets inside the scanner are 0-based like the Python original.
-- ---------------------------------------------------------------------------------------------

local sbyte, ssub, sfind, sfmt = string.byte, string.sub, string.find, string.format

local top = Proto("top", "TOP gimbal protocol")

-- -- fields ---------------------------------------------------------------------------------------

local CHECKSUM_STATUS = { [0] = "Bad", [1] = "Good" }
local pf = {
    header = ProtoField.string("top.header", "Header"),
    src = ProtoField.string("top.src", "Source address"),
    dst = ProtoField.string("top.dst", "Destination address"),
    length = ProtoField.uint16("top.length", "Length", base.DEC),
    rw = ProtoField.string("top.rw", "Control"),
    id = ProtoField.string("top.id", "Identifier"),
    name = ProtoField.string("top.name", "Command"),
    data = ProtoField.string("top.data", "Data"),
    checksum = ProtoField.string("top.checksum", "Checksum"),
    checksum_expected = ProtoField.string("top.checksum.expected", "Expected checksum"),
    checksum_status = ProtoField.uint8("top.checksum.status", "Checksum status", base.DEC, CHECKSUM_STATUS),
    dialect = ProtoField.string("top.dialect", "Dialect"),
    direction = ProtoField.string("top.direction", "Direction"),
    form = ProtoField.string("top.form", "Form"),
    fields_error = ProtoField.string("top.fields_error", "Fields not decoded"),
    null = ProtoField.string("top.field_null", "Field without a value"),
    garbage = ProtoField.bytes("top.garbage", "Bytes outside a frame"),
}
local field_pf = {}
do
    local list = {}
    for _, v in pairs(pf) do list[#list + 1] = v end
    local names = {}
    for name in pairs(GEN.field_types) do names[#names + 1] = name end
    table.sort(names)
    for _, name in ipairs(names) do
        local abbr = "top.field." .. name
        if GEN.field_types[name] == "double" then
            field_pf[name] = ProtoField.double(abbr, name)
        else
            field_pf[name] = ProtoField.string(abbr, name)
        end
        list[#list + 1] = field_pf[name]
    end
    top.fields = list
end

local ex = {
    bad_checksum = ProtoExpert.new("top.expert.bad_checksum", "Bad checksum",
        expert.group.CHECKSUM, expert.severity.WARN),
    bad_length = ProtoExpert.new("top.expert.bad_length", "Bad length",
        expert.group.MALFORMED, expert.severity.WARN),
    unknown_id = ProtoExpert.new("top.expert.unknown_id", "Unknown identifier",
        expert.group.UNDECODED, expert.severity.WARN),
    bad_fields = ProtoExpert.new("top.expert.bad_fields", "Data fit no form of the command",
        expert.group.MALFORMED, expert.severity.WARN),
    garbage = ProtoExpert.new("top.expert.garbage", "Bytes outside a frame",
        expert.group.PROTOCOL, expert.severity.NOTE),
}
top.experts = { ex.bad_checksum, ex.bad_length, ex.unknown_id, ex.bad_fields, ex.garbage }

local DIALECT_PREF = { { 1, "auto", 0 } }
for i, name in ipairs(GEN.dialect_order) do DIALECT_PREF[#DIALECT_PREF + 1] = { i + 1, name, i } end
top.prefs.dialect = Pref.enum("Dialect", 0,
    "auto: by documented port, else by the frame (P address or #tP/#Tp header: TOPOTEK first; "
    .. "else the first dialect whose forms fit)", DIALECT_PREF, false)

-- -- numbers as Python prints them ------------------------------------------------------------

local function pyfloat(v)
    if v ~= v then return "nan" end
    if v == math.huge then return "inf" end
    if v == -math.huge then return "-inf" end
    local s
    for p = 0, 16 do
        s = sfmt("%." .. p .. "e", v)
        if tonumber(s) == v then break end
    end
    local sign, lead, frac, exp = s:match("^(-?)(%d)%.?(%d*)e([-+]%d+)$")
    local digits = (lead .. frac):gsub("0+$", "")
    if digits == "" then digits = "0" end
    exp = tonumber(exp)
    if exp < -4 or exp >= 16 then
        local m = digits:sub(1, 1)
        if #digits > 1 then m = m .. "." .. digits:sub(2) end
        return sign .. m .. sfmt("e%s%02d", exp < 0 and "-" or "+", math.abs(exp))
    end
    if exp >= 0 then
        if #digits <= exp + 1 then return sign .. digits .. string.rep("0", exp + 1 - #digits) .. ".0" end
        return sign .. digits:sub(1, exp + 1) .. "." .. digits:sub(exp + 2)
    end
    return sign .. "0." .. string.rep("0", -exp - 1) .. digits
end

local function pyround(x, n)
    if x ~= x or x == math.huge or x == -math.huge then return x end
    local v = tonumber(sfmt("%." .. n .. "f", x))
    if v == 0 then v = 0.0 end
    return v
end

local function quote(raw)
    return "'" .. raw:gsub("[^\32-\126]", function(c) return sfmt("\\x%02x", sbyte(c)) end) .. "'"
end

local PY_WS = "[ \t\n\r\11\12\28\29\30\31]"
local function pystrip(s)
    return (s:gsub("^" .. PY_WS .. "+", ""):gsub(PY_WS .. "+$", ""))
end
local function bytes_strip(s)
    return (s:gsub("^[ \t\n\r\11\12]+", ""):gsub("[ \t\n\r\11\12]+$", ""))
end

-- float() of a str: sign, digits with single underscores between them, '.', exponent, inf/nan
local function parse_float(t)
    t = bytes_strip(t) -- float() strips ASCII whitespace only (str.strip() also strips \x1c-\x1f)
    local sign, word = t:lower():match("^([+-]?)(%a+)$")
    if word then
        if word == "inf" or word == "infinity" then return sign == "-" and -math.huge or math.huge end
        if word == "nan" then return 0 / 0 end
        return nil
    end
    if t:find("_", 1, true) then
        if t:find("[^%d]_") or t:find("_[^%d]") or t:find("^_") or t:find("_$") then return nil end
        t = t:gsub("_", "")
    end
    local s, mant, exp = t:match("^([+-]?)([%d%.]+)(.*)$")
    if not mant then return nil end
    if not (mant:match("^%d+%.?%d*$") or mant:match("^%.%d+$")) then return nil end
    if exp ~= "" and not exp:match("^[eE][+-]?%d+$") then return nil end
    return tonumber(s .. mant .. exp)
end

-- -- codecs: each returns value (number, string or NULL) or nil, reason ----------------------

local NULL = setmetatable({}, { __tostring = function() return "null" end })
local DECODE = {}

local function scaled(c, v)
    if c.div and c.div ~= 0 then return v / c.div end
    if c.scale == 1 then return v end
    return pyround(v * c.scale, c.dec)
end

local function none_set(c)
    if not c.none_set then
        c.none_set = {}
        for _, t in ipairs(c.none or {}) do c.none_set[t] = true end
    end
    return c.none_set
end

DECODE.hex = function(c, raw)
    if none_set(c)[raw] then return NULL end
    if #raw ~= c.w or raw:find("[^0-9A-Fa-f]") then return nil, quote(raw) .. " is not " .. c.w .. " hex digits" end
    local v = tonumber(raw, 16)
    local bits = 4 * c.w
    if c.signed and v >= 2 ^ (bits - 1) then v = v - 2 ^ bits end
    return scaled(c, v)
end

DECODE.dec = function(c, raw)
    if #raw ~= c.w or not raw:match("^%d+$") then return nil, quote(raw) .. " is not " .. c.w .. " decimal digits" end
    local v = tonumber(raw)
    if c.scale == 1 then return v end
    return pyround(v * c.scale, c.dec)
end

DECODE.float = function(c, raw)
    local set = none_set(c)
    if set[bytes_strip(raw)] or set[raw:sub(1, 3)] then return NULL end
    if c.w and #raw ~= c.w then return nil, quote(raw) .. " is not " .. c.w .. " characters" end
    if raw:find("[\128-\255]") then return nil, quote(raw) .. " is not ASCII" end
    local text = pystrip(raw)
    local low = text:lower()
    if text == "" or low == "nan" or low == "inf" or low == "-inf" or low == "+inf" or low == "infinity" then
        return nil, quote(raw) .. " is not a number"
    end
    local v = parse_float(text)
    if v == nil then return nil, "could not convert " .. quote(text) .. " to float" end
    return pyround(v, c.decimals)
end

DECODE.bin = function(c, raw)
    if #raw ~= c.w then return nil, #raw .. " bytes where " .. c.w .. " are needed" end
    local v = 0
    for k = 1, c.w do
        local b = c.little and sbyte(raw, c.w - k + 1) or sbyte(raw, k)
        v = v * 256 + b
    end
    if c.signed and v >= 2 ^ (8 * c.w - 1) then v = v - 2 ^ (8 * c.w) end
    if c.scale == 1 then return v end
    return pyround(v * c.scale, c.dec)
end

DECODE.bitrate = function(c, raw)
    local first = raw:sub(1, 1)
    if (first == "K" or first == "k") and #raw == 6 and raw:sub(2):match("^%d+$") then
        return tonumber(raw:sub(2))
    end
    if (#raw == 2 or #raw == 6) and raw:sub(1, 2):match("^%d%d$") then return tonumber(raw:sub(2, 2)) * 1000 end
    if #raw == 1 and raw:match("^%d$") then return tonumber(raw) * 1000 end
    return nil, quote(raw) .. " is not 0M0000, Kddddd or a Mbps digit"
end

DECODE.enum = function(c, raw)
    local v = c.map[raw]
    if v == nil then return nil, quote(raw) .. " is not in the table" end
    return v.name, v.label
end

DECODE.oneof = function(c, raw)
    local v, label = DECODE.enum(c.tokens, raw)
    if v ~= nil then return v, label end
    return DECODE[c.number.k](c.number, raw)
end

local function latin1(raw) -- Python decodes text as latin-1; Wireshark wants UTF-8
    return (raw:gsub("[\128-\255]", function(ch)
        local b = sbyte(ch)
        return string.char(0xC0 + math.floor(b / 64), 0x80 + b % 64)
    end))
end

DECODE.text = function(c, raw)
    if #raw < c.min or #raw > c.max then
        return nil, #raw .. " characters, expected " .. c.min .. ".." .. c.max
    end
    return latin1(raw)
end

DECODE.ipv4 = function(c, raw)
    local bad = quote(raw) .. " is not a dotted IPv4 address"
    if raw:find("[\128-\255]") then return nil, bad end
    local parts = {}
    for part in (raw .. "."):gmatch("([^.]*)%.") do parts[#parts + 1] = part end
    if #parts ~= 4 then return nil, bad end
    for _, p in ipairs(parts) do
        if p == "" or #p > 3 or not p:match("^%d+$") or tonumber(p) > 255 or (#p > 1 and p:sub(1, 1) == "0") then
            return nil, bad
        end
    end
    return raw
end

DECODE.raw = function(c, raw)
    if c.w and #raw ~= c.w then return nil, #raw .. " bytes where " .. c.w .. " are needed" end
    return (raw:gsub(".", function(ch) return sfmt("%02x", sbyte(ch)) end))
end

DECODE.literal = function(c, raw)
    if raw ~= c.text then return nil, quote(raw) .. " is not " .. quote(c.text) end
    return raw
end

-- Coordinates: a hemisphere letter, then digits with the point at a fixed place (spaces ignored).
local function hemisphere(c, raw, what_lat, what_lon)
    local lat = c.axis == "lat"
    local bad = quote(raw) .. " is not " .. (lat and what_lat or what_lon)
    if raw:find("[\128-\255]") then return nil, bad end
    local text = raw:gsub(" ", "")
    local sign = (lat and { N = 1, S = -1 } or { E = 1, W = -1 })[text:sub(1, 1):upper()]
    local body = text:sub(2)
    local dot = body:find(".", 1, true)
    if not sign or not dot then return nil, bad end
    return sign, body, dot - 1, lat, bad
end

DECODE.geodm = function(c, raw)
    local sign, body, dot, lat, bad = hemisphere(c, raw, "N/S ddmm.mmmm", "E/W dddmm.mmmm")
    if not sign then return nil, body end
    local nodot = body:sub(1, dot) .. body:sub(dot + 2)
    if dot ~= (lat and 4 or 5) or not nodot:match("^%d+$") then return nil, bad end
    local deg, minutes = tonumber(body:sub(1, dot - 2)), tonumber(body:sub(dot - 1))
    if minutes >= 60 then return nil, quote(raw) .. ": minutes " .. pyfloat(minutes) .. " >= 60" end
    return pyround(sign * (deg + minutes / 60), 7)
end

DECODE.geodeg = function(c, raw)
    local sign, body, dot, lat, bad = hemisphere(c, raw, "N/S dd.dddddd", "E/W ddd.dddddd")
    if not sign or dot ~= (lat and 2 or 3) then return nil, sign and bad or body end
    local v = parse_float(body)
    if v == nil then return nil, bad end
    return pyround(sign * v, 7)
end

local TWO_DIGIT = {
    m = function(s) return s:match("^1[0-2]$") or s:match("^0[1-9]$") end,
    d = function(s) return s:match("^3[01]$") or s:match("^[12]%d$") or s:match("^0[1-9]$") or s:match("^ [1-9]$") end,
    H = function(s) return s:match("^2[0-3]$") or s:match("^[01]%d$") end,
    M = function(s) return s:match("^[0-5]%d$") end,
    S = function(s) return s:match("^[0-5]%d$") end, -- 60 and 61 parse, then datetime refuses them
    y = function(s) return s:match("^%d%d$") end,
    Y = function(s) return s:match("^%d%d%d%d$") end,
}
local function days_in_month(y, m)
    if m == 2 then return ((y % 4 == 0 and y % 100 ~= 0) or y % 400 == 0) and 29 or 28 end
    return ({ 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31 })[m]
end

DECODE.time = function(c, raw)
    local width = 0
    for _, seg in ipairs(c.segments) do width = width + (seg.w or 1) end
    if raw:find("[\128-\255]") then return nil, quote(raw) .. " is not ASCII" end
    if #raw ~= width then return nil, quote(raw) .. " is not " .. width .. " characters" end
    local t, at = { Y = 1900, m = 1, d = 1, H = 0, M = 0, S = 0, f2 = 0 }, 1
    local bad = quote(raw) .. " does not match the time layout"
    for _, seg in ipairs(c.segments) do
        if seg.lit then
            if raw:sub(at, at) ~= seg.lit then return nil, bad end
            at = at + 1
        else
            local s = raw:sub(at, at + seg.w - 1)
            at = at + seg.w
            if seg.d == "f2" then
                local n = pystrip(s):match("^[+-]?%d+$") and tonumber((pystrip(s):gsub("^%+", "")))
                if n == nil or n < 0 then return nil, bad end
                t.f2 = n
            else
                if not TWO_DIGIT[seg.d](s) then return nil, bad end
                local n = tonumber(s)
                if seg.d == "y" then t.Y = 2000 + n else t[seg.d] = n end
            end
        end
    end
    if t.Y < 1 or t.S > 59 or t.d > days_in_month(t.Y, t.m) then return nil, bad end
    local iso = sfmt("%04d-%02d-%02dT%02d:%02d:%02d", t.Y, t.m, t.d, t.H, t.M, t.S)
    if t.f2 > 0 then iso = iso .. sfmt(".%06d", t.f2 * 10000) end
    return iso
end

-- -- catalog lookups ---------------------------------------------------------------------------

local DEVICE, HOST = {}, {}
for ch in GEN.device_addresses:gmatch(".") do DEVICE[ch] = true end
for ch in GEN.host_addresses:gmatch(".") do HOST[ch] = true end

local function direction_of(src, dst)
    return (DEVICE[src] and HOST[dst]) and "response" or "request"
end

local function decode_form(form, data)
    if form.const then
        if data ~= form.const then return nil, "expected " .. quote(form.const) end
        return {}
    end
    local values = {}
    for _, f in ipairs(form.fields) do
        local a, b = f.a, f.b or #data
        local c = GEN.codecs[f.c]
        local v, label = DECODE[c.k](c, data:sub(a + 1, b))
        if v == nil then return nil, label end
        values[#values + 1] = { field = f, codec = c, value = v, label = label, a = a, b = b }
    end
    return values
end

-- The Python decoder's Dialect.decode: forms of the frame's direction first, then the other's.
local function decode_in(dname, fr)
    local d = GEN.dialects[dname]
    local spec = d.commands[fr.ident]
    if spec == nil then
        return { dialect = dname, error = quote(fr.ident) .. " is not in the " .. dname .. " catalog" }
    end
    local dir = direction_of(fr.src, fr.dst)
    local rw = fr.rw ~= "" and fr.rw or "w"
    local forms = d.index[fr.ident .. "|" .. rw .. "|" .. dir] or {}
    local n = #fr.data
    local last = fr.ident .. " has no '" .. rw .. "' form for a " .. dir
    for _, fi in ipairs(forms) do
        local form = spec.forms[fi]
        if n < form.min or n > form.max then
            local takes = {}
            for _, fj in ipairs(forms) do
                local o = spec.forms[fj]
                takes[#takes + 1] = o.min == o.max and tostring(o.min) or (o.min .. ".." .. o.max)
            end
            last = n .. " data bytes; " .. fr.ident .. " (" .. rw .. ") takes " .. table.concat(takes, " or ")
        else
            local values, err = decode_form(form, fr.data)
            if values then return { dialect = dname, spec = spec, form = form, values = values } end
            last = fr.ident .. ": " .. err
        end
    end
    return { dialect = dname, spec = spec, error = last }
end

local function port_dialect(pinfo)
    local ports = GEN.ports[pinfo.port_type == 2 and "tcp" or "udp"] or {}
    for _, port in ipairs({ pinfo.src_port, pinfo.dst_port }) do
        if ports[port] then return ports[port], port end
    end
end

-- Dialect choice: the preference, else a documented port, else by the frame (as `topgimbal decode`).
local function decode_frame(fr, pinfo)
    local forced = top.prefs.dialect
    if forced and forced > 0 then return decode_in(GEN.dialect_order[forced], fr), "preference" end
    local by_port, port = port_dialect(pinfo)
    if by_port then return decode_in(by_port, fr), "port " .. port end
    local order = GEN.dialect_order
    if fr.src == "P" or fr.dst == "P" or fr.header == "#tP" or fr.header == "#Tp" then
        order = {}
        for i = #GEN.dialect_order, 1, -1 do order[#order + 1] = GEN.dialect_order[i] end
    end
    local first
    for _, name in ipairs(order) do
        local msg = decode_in(name, fr)
        first = first or msg
        if msg.values then return msg, "frame" end
    end
    return first, "frame"
end

-- -- the scanner (FrameParser._scan and friends, 0-based offsets) -------------------------------

local HEXVAL, ADDR, RW = {}, {}, { [sbyte("r")] = true, [sbyte("w")] = true }
for i = 0, 255 do HEXVAL[i] = -1 end
for i = 0, 15 do
    HEXVAL[sbyte("0123456789ABCDEF", i + 1)] = i
    if i >= 10 then HEXVAL[sbyte("abcdef", i - 9)] = i end
end
for ch in pairs(GEN.addresses) do ADDR[sbyte(ch)] = true end
local HDR = { TP = "#TP", tp = "#tp", tP = "#tP", Tp = "#Tp" }
local ASCII_MAX_TOTAL = 12 + GEN.max_ascii_length

local function B(buf, k) return sbyte(buf, k + 1) end
local function S(buf, a, b) return ssub(buf, a + 1, b) end
local function find_hash(buf, start, stop)
    local k = sfind(buf, "#", start + 1, true)
    if k == nil or (stop and k - 1 >= stop) then return -1 end
    return k - 1
end
local function sum8(buf, a, b)
    local s = 0
    for k = a + 1, b do s = s + sbyte(buf, k) end
    return s % 256
end

-- Identifiers are three ASCII letters or digits (the parser's rule since it gained
-- `is_identifier`; GEN.strict_identifier says whether the catalog this file came from has it).
local STRICT = GEN.strict_identifier
local IDENT = {}
for ch in ("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789"):gmatch(".") do IDENT[sbyte(ch)] = true end

-- Whether the bytes already after the '#' at i rule out a frame (garbage is dropped at once
-- instead of waiting for bytes that cannot make it one).
local function bad_prefix(buf, i, n_buf)
    if n_buf <= i + 2 then
        local c = B(buf, i + 1)
        return n_buf > i + 1 and c ~= 84 and c ~= 116 -- 'T', 't'
    end
    local hdr = S(buf, i + 1, i + 3)
    if not HDR[hdr] then return true end
    for k = 3, 4 do
        if n_buf > i + k and not ADDR[B(buf, i + k)] then return true end
    end
    if n_buf > i + 5 and (hdr == "TP" or hdr == "tp") and HEXVAL[B(buf, i + 5)] < 0 then return true end
    if n_buf > i + 6 and hdr ~= "Tp" and not RW[B(buf, i + 6)] then return true end
    for k = 7, 9 do
        if n_buf > i + k and not IDENT[B(buf, i + k)] then return true end
    end
    return false
end

local function frame_end(buf, i)
    local n_buf = #buf
    if STRICT and n_buf < i + 10 then return bad_prefix(buf, i, n_buf) and -1 or -2 end
    if n_buf < i + 7 then
        if n_buf > i + 2 and not HDR[S(buf, i + 1, i + 3)] then return -1 end
        for k = 3, 4 do
            if n_buf > i + k and not ADDR[B(buf, i + k)] then return -1 end
        end
        return -2
    end
    local hdr = S(buf, i + 1, i + 3)
    if not HDR[hdr] or not ADDR[B(buf, i + 3)] or not ADDR[B(buf, i + 4)] then return -1 end
    if STRICT and not (IDENT[B(buf, i + 7)] and IDENT[B(buf, i + 8)] and IDENT[B(buf, i + 9)]) then return -1 end
    local n
    if hdr == "TP" or hdr == "tp" then
        n = HEXVAL[B(buf, i + 5)]
        if n < 0 or not RW[B(buf, i + 6)] then return -1 end
    elseif hdr == "tP" then
        n = B(buf, i + 5)
        if not RW[B(buf, i + 6)] then return -1 end
    else
        n = B(buf, i + 5) * 256 + B(buf, i + 6)
    end
    if n > GEN.max_data_length then return -3 end
    return i + 12 + n
end

-- Any case mix of the two hex characters (FrameParser's look-ahead and length recovery).
local function good_checksum(buf, a, e)
    local crc = S(buf, e - 2, e)
    return crc:upper() == sfmt("%02X", sum8(buf, a, e - 2))
end

-- All upper or all lower case (FrameParser's check of a frame at its declared length).
local function exact_checksum(buf, a, e)
    local crc, s = S(buf, e - 2, e), sum8(buf, a, e - 2)
    return crc == sfmt("%02X", s) or crc == sfmt("%02x", s)
end

local function valid_complete_at(buf, j)
    local e = frame_end(buf, j)
    if e < 0 or e > #buf then return false end
    return good_checksum(buf, j, e)
end

-- For a frame at i whose checksum is right: the start of the first valid frame that begins inside
-- it (-1 if none, nil if bytes still to come decide). Such a frame wins: the outer one matched its
-- checksum by chance.
local function inner_frame(buf, i, e, final)
    local n_buf = #buf
    local j = find_hash(buf, i + 1, e)
    while j >= 0 do
        local e2 = frame_end(buf, j)
        if e2 == -2 or e2 > n_buf then
            if not final then return nil end
        elseif e2 > 0 and valid_complete_at(buf, j) then
            return j
        end
        j = find_hash(buf, j + 1, e)
    end
    return -1
end

local function discard(buf, a, b, out, why, kind)
    if not S(buf, a, b):find("[^\r\n]") then return end
    out[#out + 1] = { kind = kind or "garbage", detail = why, a = a, b = b }
end

-- The frame at i at another length whose checksum is right and that ends exactly where the next
-- thing starts; false if none, nil if bytes still to come decide it.
local function recover(buf, i, final)
    local n_buf = #buf
    local limit = math.min(n_buf, i + ASCII_MAX_TOTAL)
    local boundary
    for k = i + 1, limit - 1 do
        local b = B(buf, k)
        if b == 0x23 or b == 0x0D or b == 0x0A then boundary = k; break end
    end
    if boundary == nil then
        if not final and n_buf < i + ASCII_MAX_TOTAL then return nil end
        boundary = limit
    end
    local n = boundary - i - 12
    local declared = HEXVAL[B(buf, i + 5)]
    if n < 0 or n > 15 or n == declared then return false end
    if not good_checksum(buf, i, boundary) then return false end
    if S(buf, i + 10, boundary - 2):find("[^\32-\126]") then return false end
    return { kind = "frame", a = i, b = boundary, declared = declared }
end

local function scan(buf, pos, out, final)
    local n_buf = #buf
    while pos < n_buf do
        repeat -- `break` below continues the outer loop
            local i = find_hash(buf, pos)
            if i < 0 then
                discard(buf, pos, n_buf, out, "bytes outside a frame")
                return n_buf
            end
            if i > pos then
                discard(buf, pos, i, out, "bytes outside a frame")
                pos = i
            end
            local e = frame_end(buf, i)
            if e == -2 then return i end
            if e == -1 then
                discard(buf, i, i + 1, out, "'#' not followed by a valid header/address/length", "bad_header")
                pos = i + 1
                break
            end
            if e == -3 then
                discard(buf, i, i + 1, out, "declared length above the " .. GEN.max_data_length .. "-byte bound", "oversize")
                pos = i + 1
                break
            end
            local hdr = S(buf, i + 1, i + 3)
            if e > n_buf then
                local j = find_hash(buf, i + 1)
                while j >= 0 and not valid_complete_at(buf, j) do j = find_hash(buf, j + 1) end
                if j < 0 then return i end
                if hdr == "TP" or hdr == "tp" then
                    local rec = recover(buf, i, true)
                    if rec then
                        out[#out + 1] = rec
                        pos = rec.b
                        break
                    end
                end
                discard(buf, i, j, out, "incomplete frame followed by a good one", "bad_length")
                pos = j
                break
            end
            if exact_checksum(buf, i, e) then
                local inner = -1
                if STRICT and find_hash(buf, i + 1, e) >= 0 then inner = inner_frame(buf, i, e, final) end
                if inner == nil then return i end -- a frame that starts inside this one is still arriving
                if inner >= 0 then
                    discard(buf, i, inner, out, "checksum matched by chance: a frame starts inside")
                    pos = inner
                    break
                end
                out[#out + 1] = { kind = "frame", a = i, b = e }
                pos = e
                break
            end
            if hdr == "TP" or hdr == "tp" then
                local rec = recover(buf, i, final)
                if rec == nil then return i end
                if rec then
                    out[#out + 1] = rec
                    pos = rec.b
                    break
                end
            end
            local nxt = find_hash(buf, i + 1, e)
            if nxt < 0 then nxt = e end
            out[#out + 1] = { kind = "bad_checksum", a = i, b = e }
            pos = nxt
        until true
    end
    return pos
end

-- -- the tree -----------------------------------------------------------------------------------

local HEADER_KIND = {
    ["#TP"] = "length as one hex character",
    ["#tp"] = "length as one hex character",
    ["#tP"] = "length as one raw byte",
    ["#Tp"] = "16-bit length, no control character",
}
local CONTROL = { r = "r (query)", w = "w (set / control)" }

local function show(v, c)
    if v == NULL then return "null" end
    if type(v) == "number" then
        if c.int and v == math.floor(v) then return sfmt("%d", v) end
        return pyfloat(v)
    end
    return v
end

local function split_frame(buf, item)
    local a, b = item.a, item.b
    local header = S(buf, a, a + 3)
    local fr = { header = header, src = S(buf, a + 3, a + 4), dst = S(buf, a + 4, a + 5) }
    if header == "#Tp" then
        fr.length, fr.rw = B(buf, a + 5) * 256 + B(buf, a + 6), ""
    elseif header == "#tP" then
        fr.length, fr.rw = B(buf, a + 5), S(buf, a + 6, a + 7)
    else
        fr.length, fr.rw = HEXVAL[B(buf, a + 5)], S(buf, a + 6, a + 7)
    end
    fr.ident = S(buf, a + 7, a + 10)
    fr.data = S(buf, a + 10, b - 2)
    fr.crc = S(buf, b - 2, b)
    fr.expected = sfmt("%02X", sum8(buf, a, b - 2))
    return fr
end

local function add_frame(tvb, pinfo, tree, buf, item)
    local a, b = item.a, item.b
    local fr = split_frame(buf, item)
    local msg, why = decode_frame(fr, pinfo)
    local ok = item.kind == "frame"
    local name = msg.spec and msg.spec.name or "unknown"
    local sub = tree:add(top, tvb(a, b - a), "TOP " .. fr.ident .. " " .. name .. " (" .. msg.dialect .. ")")
    local names = GEN.addresses
    sub:add(pf.header, tvb(a, 3), fr.header, "Header: " .. fr.header .. " (" .. HEADER_KIND[fr.header] .. ")")
    sub:add(pf.src, tvb(a + 3, 1), fr.src, "Source: " .. fr.src .. " (" .. (names[fr.src] or "?") .. ")")
    sub:add(pf.dst, tvb(a + 4, 1), fr.dst, "Destination: " .. fr.dst .. " (" .. (names[fr.dst] or "?") .. ")")
    local len_range = fr.header == "#Tp" and tvb(a + 5, 2) or tvb(a + 5, 1)
    local len_item = sub:add(pf.length, len_range, fr.length)
    if item.declared then
        len_item:add_proto_expert_info(ex.bad_length, "Bad length: the length character says " .. item.declared
            .. ", the frame has " .. #fr.data .. " data bytes (the checksum proves the real length)")
    end
    if fr.rw ~= "" then sub:add(pf.rw, tvb(a + 6, 1), fr.rw, "Control: " .. (CONTROL[fr.rw] or fr.rw)) end
    local id_item = sub:add(pf.id, tvb(a + 7, 3), fr.ident,
        "Identifier: " .. fr.ident .. (msg.spec and (" (" .. msg.spec.name .. ": " .. msg.spec.title .. ")") or ""))
    if msg.spec then
        sub:add(pf.name, tvb(a + 7, 3), msg.spec.name):set_generated()
    else
        id_item:add_proto_expert_info(ex.unknown_id, "Unknown identifier: " .. msg.error)
    end
    if #fr.data > 0 then
        -- binary data (TOPOTEK GPS/UAV structs) shown as \xNN, as `topgimbal decode` does
        local shown = fr.data:gsub("[^\32-\126]", function(ch) return sfmt("\\x%02x", sbyte(ch)) end)
        sub:add(pf.data, tvb(a + 10, #fr.data), shown)
    end
    local crc_item = sub:add(pf.checksum, tvb(b - 2, 2), fr.crc,
        "Checksum: " .. fr.crc .. (ok and " [correct]" or (" [incorrect, should be " .. fr.expected .. "]")))
    crc_item:add(pf.checksum_status, tvb(b - 2, 2), ok and 1 or 0):set_generated()
    if not ok then
        crc_item:add(pf.checksum_expected, tvb(b - 2, 2), fr.expected):set_generated()
        crc_item:add_proto_expert_info(ex.bad_checksum, "Bad checksum: " .. fr.crc .. " on the wire, expected " .. fr.expected)
    end
    sub:add(pf.dialect, tvb(a, b - a), msg.dialect, "Dialect: " .. msg.dialect .. " (by " .. why .. ")"):set_generated()
    local dir = direction_of(fr.src, fr.dst)
    sub:add(pf.direction, tvb(a + 3, 2), dir == "response" and "device->host" or "host->device"):set_generated()
    local summary = { fr.ident, name }
    if msg.form then
        local role = msg.form.role ~= "" and (" " .. msg.form.role) or ""
        sub:add(pf.form, tvb(a + 10, #fr.data), msg.form.rw .. " " .. msg.form.dir .. " " .. msg.form.title .. role)
            :set_generated()
        if #msg.values == 0 then summary[#summary + 1] = msg.form.title end
        for _, v in ipairs(msg.values) do
            local f, c = v.field, v.codec
            local text = show(v.value, c)
            local unit = (v.value ~= NULL and c.unit ~= "") and (" " .. c.unit) or ""
            local raw = fr.data:sub(v.a + 1, v.b)
            local label = f.n .. ": " .. text .. unit .. (v.label and v.label ~= text and (" (" .. v.label .. ")") or "")
                .. "  [" .. quote(raw) .. "]" .. (f.d ~= "" and ("  " .. f.d) or "")
            local range = tvb(a + 10 + v.a, v.b - v.a)
            if v.value == NULL then
                sub:add(pf.null, range, f.n, label)
            elseif GEN.field_types[f.n] == "double" then
                sub:add(field_pf[f.n], range, v.value, label)
            else
                sub:add(field_pf[f.n], range, text, label)
            end
            summary[#summary + 1] = f.s .. "=" .. text
        end
    elseif msg.spec then
        local it = sub:add(pf.fields_error, tvb(a + 10, #fr.data), msg.error)
        it:add_proto_expert_info(ex.bad_fields, "Data fit no form of " .. fr.ident .. ": " .. msg.error)
        summary[#summary + 1] = "[data fit no form]"
    else
        summary[#summary + 1] = "[unknown identifier]"
    end
    if not ok then summary[#summary + 1] = "[bad checksum]" end
    if item.declared then summary[#summary + 1] = "[bad length]" end
    return table.concat(summary, " ")
end

local GARBAGE_TEXT = {
    garbage = "Bytes outside a frame",
    bad_header = "'#' without a valid header",
    oversize = "Bad length: declared length above the bound",
    bad_length = "Bad length",
    truncated = "Bad length: frame truncated",
}

local function add_garbage(tvb, tree, item)
    local text = (GARBAGE_TEXT[item.kind] or "Bytes outside a frame") .. ": " .. item.detail
    local sub = tree:add(top, tvb(item.a, item.b - item.a), "TOP " .. text)
    local it = sub:add(pf.garbage, tvb(item.a, item.b - item.a))
    it:set_text(text)
    local ef = (item.kind == "garbage" or item.kind == "bad_header") and ex.garbage or ex.bad_length
    it:add_proto_expert_info(ef, item.detail)
    if ef == ex.bad_length then return "[bad length]" end
    return nil
end

-- -- TCP: items shown once ----------------------------------------------------------------------
-- When the dissector asks TCP for more bytes at an offset inside the part of a reassembled buffer
-- that came from earlier segments, Wireshark extends that reassembly and hands the same bytes over
-- again. Items are therefore placed in the stream (absolute position of their first byte) and
-- shown in the first packet that produced them; a re-dissection (GUI) shows the same ones again.

local f_tcp_stream, f_tcp_seq, f_tcp_len = Field.new("tcp.stream"), Field.new("tcp.seq"), Field.new("tcp.len")
local last_start = {} -- direction key -> absolute start of the last item shown
local owned = {}      -- packet number -> { [absolute start] = true }

local function stream_position(pinfo, len)
    local stream, seq, seglen = f_tcp_stream(), f_tcp_seq(), f_tcp_len()
    if not (stream and seq and seglen) then return nil end
    -- the buffer always ends with the current segment's payload
    return tostring(stream.value) .. ":" .. pinfo.src_port, seq.value + seglen.value - len
end

local function first_showing(out, pinfo, len)
    local key, base = stream_position(pinfo, len)
    if not key then return out end
    local keep = {}
    if pinfo.visited then
        local mine = owned[pinfo.number] or {}
        for _, item in ipairs(out) do
            if mine[base + item.a] then keep[#keep + 1] = item end
        end
        return keep
    end
    local mine = owned[pinfo.number] or {}
    for _, item in ipairs(out) do
        local at = base + item.a
        if last_start[key] == nil or at > last_start[key] then
            keep[#keep + 1] = item
            mine[at] = true
            last_start[key] = at
        end
    end
    owned[pinfo.number] = mine
    return keep
end

function top.init()
    last_start, owned = {}, {}
end

-- -- entry points -----------------------------------------------------------------------------

-- A local function: the heuristic calls it directly (calling `top.dissector` would go through
-- Wireshark's call_dissector, which uses up the permission to ask TCP for more bytes).
local function dissect(tvb, pinfo, tree)
    local len = tvb:len()
    if len == 0 then return 0 end
    local buf = tvb:raw(0, len)
    local out = {}
    local stream = pinfo.can_desegment > 0
    local pos = scan(buf, 0, out, false)
    if stream and pos < len then
        pinfo.desegment_offset = pos
        pinfo.desegment_len = DESEGMENT_ONE_MORE_SEGMENT
    elseif pos < len then
        -- end of a datagram: resolve what waits (FrameParser.feed_datagram = feed + flush)
        local rest = scan(buf, pos, out, true)
        if rest < len then discard(buf, rest, len, out, "incomplete frame at end of stream", "truncated") end
    end
    if stream then out = first_showing(out, pinfo, len) end
    if #out == 0 then return len end
    pinfo.cols.protocol = "TOP"
    local infos = {}
    for _, item in ipairs(out) do
        local info
        if item.kind == "frame" or item.kind == "bad_checksum" then
            info = add_frame(tvb, pinfo, tree, buf, item)
        else
            info = add_garbage(tvb, tree, item)
        end
        if info then infos[#infos + 1] = info end
    end
    if #infos > 0 then pinfo.cols.info = table.concat(infos, " | ") end
    return len
end
top.dissector = dissect

local function heuristic(tvb, pinfo, tree)
    local len = tvb:len()
    if len < 3 then return false end
    local head = tvb:raw(0, math.min(len, 16)):gsub("^[\r\n]+", "")
    if #head < 3 or head:sub(1, 1) ~= "#" or not HDR[head:sub(2, 3)] then return false end
    for k = 4, math.min(#head, 5) do
        if not ADDR[sbyte(head, k)] then return false end
    end
    pinfo.conversation = top
    dissect(tvb, pinfo, tree)
    return true
end

do
    local udp, tcp = DissectorTable.get("udp.port"), DissectorTable.get("tcp.port")
    for port in pairs(GEN.ports.udp) do udp:add(port, top) end
    for port in pairs(GEN.ports.tcp) do tcp:add(port, top) end
    top:register_heuristic("udp", heuristic)
    top:register_heuristic("tcp", heuristic)
end
