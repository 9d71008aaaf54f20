-- ---------------------------------------------------------------------------------------------
-- Core (fixed; the tables above are generated): pure Lua, no Wireshark API, so a test runs it
-- under every Lua a Wireshark embeds (5.2 up to Wireshark 4.2, 5.3/5.4 from 4.4 on).
--
-- Frame scanning follows topgimbal's FrameParser rule for rule (resync at the next '#', a good
-- frame never held back by garbage, length recovery when the checksum proves the real length),
-- field decoding follows each codec class of the catalog, and the dialect choice follows
-- `protocol.decode_any` (the preferred dialect first, then the others as `guess_dialects` ranks
-- them), so Wireshark shows what `topgimbal decode` shows. Offsets inside the scanner are 0-based
-- like the Python original.
--
-- Portable across Lua 5.2-5.4: no bit32 (gone in 5.4), no integer division operator or bitwise
-- operators (not in 5.2), no string.pack; numbers that must print as integers go through "%d"
-- only when they are whole, and every float shown is printed as Python's repr prints it.
-- ---------------------------------------------------------------------------------------------

local sbyte, ssub, sfind, sfmt = string.byte, string.sub, string.find, string.format

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

-- Python's round(x, n) (correctly rounded, as C's printf is), always a float like Python's.
local function pyround(x, n)
    if x ~= x or x == math.huge or x == -math.huge then return x end
    local v = tonumber(sfmt("%." .. n .. "f", x))
    if v == 0 then v = 0.0 end
    return v + 0.0
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

-- float() of a str without underscores (DecFloat refuses them): sign, digits with at most one
-- '.', an optional exponent. Lua's tonumber would also take hex, which float() does not.
local function parse_float(t)
    local s, mant, exp = t:match("^([+-]?)([%d%.]+)(.*)$")
    if not mant then return nil end
    if not (mant:match("^%d+%.?%d*$") or mant:match("^%.%d+$")) then return nil end
    if exp ~= "" and not exp:match("^[eE][+-]?%d+$") then return nil end
    local v = tonumber(s .. mant .. exp)
    return v and v + 0.0
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

local NOT_A_NUMBER = { nan = true, inf = true, infinity = true }

DECODE.float = function(c, raw)
    local set = none_set(c)
    if set[bytes_strip(raw)] or set[raw:sub(1, 3)] then return NULL end
    if c.w and #raw ~= c.w then return nil, quote(raw) .. " is not " .. c.w .. " characters" end
    if raw:find("[\128-\255]") then return nil, quote(raw) .. " is not ASCII" end
    local text = pystrip(raw)
    if text == "" or NOT_A_NUMBER[(text:lower():gsub("^[+-]+", ""))] or text:find("_", 1, true) then
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

-- TOPOTEK BIT: Kddddd (kbps), 0M0000 or 0M (M Mbps), or a lone Mbps digit.
DECODE.bitrate = function(c, raw)
    local first = raw:sub(1, 1)
    if #raw == 6 and (first == "K" or first == "k") and raw:sub(2):match("^%d+$") then
        return tonumber(raw:sub(2))
    end
    if (#raw == 2 or #raw == 6) and first == "0" and raw:sub(2, 2):match("^%d$")
        and (#raw == 2 or raw:sub(3):match("^%d+$")) then
        return tonumber(raw:sub(2, 2)) * 1000
    end
    if #raw == 1 and raw:match("^%d$") then return tonumber(raw) * 1000 end
    return nil, quote(raw) .. " is not 0M0000, Kddddd, 0M or a Mbps digit"
end

DECODE.enum = function(c, raw)
    local v = c.map[raw]
    if v == nil then return nil, quote(raw) .. " is not in the table" end
    return v.name, v.term and (v.label .. ", " .. v.term) or v.label
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

-- Coordinates (Geo): a hemisphere letter, then digits with the point at a fixed place (spaces
-- ignored); style "dm" is NMEA degrees and minutes, "deg" decimal degrees.
local HEMISPHERES = { lat = { N = 1, S = -1 }, lon = { E = 1, W = -1 } }
local GEO_PATTERN = {
    dm = { lat = "N/S ddmm.mmmm", lon = "E/W dddmm.mmmm" },
    deg = { lat = "N/S dd.dddddd", lon = "E/W ddd.dddddd" },
}

DECODE.geo = function(c, raw)
    local bad = quote(raw) .. " is not " .. GEO_PATTERN[c.style][c.axis]
    if raw:find("[\128-\255]") then return nil, bad end
    local text = raw:gsub(" ", "")
    local sign, body = HEMISPHERES[c.axis][text:sub(1, 1):upper()], text:sub(2)
    local point = (c.axis == "lat" and 2 or 3) + (c.style == "dm" and 2 or 0) -- digits before '.'
    if not sign or body:find(".", 1, true) ~= point + 1 or #body - point - 1 < 1
        or not (body:sub(1, point) .. body:sub(point + 2)):match("^%d+$") then
        return nil, bad
    end
    local v
    if c.style == "dm" then
        local minutes = tonumber(body:sub(point - 1))
        if minutes >= 60 then return nil, quote(raw) .. ": minutes " .. pyfloat(minutes + 0.0) .. " >= 60" end
        v = tonumber(body:sub(1, point - 2)) + minutes / 60
    else
        v = tonumber(body) + 0.0
    end
    if v > c.limit then return nil, quote(raw) .. " is beyond " .. c.limit .. " degrees" end
    return pyround(sign * v, 7)
end

-- Timestamp: fixed-width decimal fields (strptime's, which backtrack to no other full match
-- once the text is digits and the layout's literals).
local TWO_DIGIT = {
    m = function(s) return s:match("^1[0-2]$") or s:match("^0[1-9]$") end,
    d = function(s) return s:match("^3[01]$") or s:match("^[12]%d$") or s:match("^0[1-9]$") end,
    H = function(s) return s:match("^2[0-3]$") or s:match("^[01]%d$") end,
    M = function(s) return s:match("^[0-5]%d$") end,
    S = function(s) return s:match("^[0-5]%d$") end, -- 60 and 61 parse, then datetime refuses them
    y = function(s) return s:match("^%d%d$") end,
    Y = function(s) return s:match("^%d%d%d%d$") end,
    f2 = function(s) return s:match("^%d%d$") end,
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
    local bad = quote(raw) .. " does not match the time layout"
    if not raw:gsub("%.", ""):match("^%d+$") then return nil, bad end
    local t, at = { Y = 1900, m = 1, d = 1, H = 0, M = 0, S = 0, f2 = 0 }, 1
    for _, seg in ipairs(c.segments) do
        if seg.lit then
            if raw:sub(at, at) ~= seg.lit then return nil, bad end
            at = at + 1
        else
            local s = raw:sub(at, at + seg.w - 1)
            at = at + seg.w
            if not TWO_DIGIT[seg.d](s) then return nil, bad end
            local n = tonumber(s)
            if seg.d == "y" then t.Y = 2000 + n else t[seg.d] = n end
        end
    end
    if t.Y < 1 or t.d > days_in_month(t.Y, t.m) then return nil, bad end
    local iso = sfmt("%04d-%02d-%02dT%02d:%02d:%02d", t.Y, t.m, t.d, t.H, t.M, t.S)
    if t.f2 > 0 then iso = iso .. sfmt(".%06d", t.f2 * 10000) end
    return iso
end

-- A decoded value as Python prints it (whole numbers of integer codecs without a point).
local function show(v, c)
    if v == NULL then return "null" end
    if type(v) == "number" then
        if c.int and v == math.floor(v) then return sfmt("%d", v) end
        return pyfloat(v)
    end
    return v
end

-- -- catalog lookups and the dialect choice ------------------------------------------------------

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

-- Dialect.decode: forms of the frame's direction first, then the other's. `d` is { name = the
-- dialect, variant = a model whose own dialect decodes some commands differently, or nil }.
local function decode_in(d, fr)
    local dname = d.name
    local base, var = GEN.dialects[dname], d.variant and GEN.variants[d.variant]
    local spec = (var and var.commands[fr.ident]) or base.commands[fr.ident]
    local msg = { dialect = dname, variant = d.variant }
    if spec == nil then
        msg.error = quote(fr.ident) .. " is not in the " .. dname .. " catalog"
        return msg
    end
    msg.spec = spec
    local dir = direction_of(fr.src, fr.dst)
    local rw = fr.rw ~= "" and fr.rw or "w"
    local key = fr.ident .. "|" .. rw .. "|" .. dir
    local index = (var and var.commands[fr.ident]) and var.index or base.index
    local forms = index[key] or {}
    local n = #fr.data
    local last = fr.ident .. " has no '" .. rw .. "' form for a " .. dir
    for _, fi in ipairs(forms) do
        local form = spec.forms[fi]
        if n < form.min or n > form.max then
            local takes = {}
            for _, fj in ipairs(forms) do
                local o = spec.forms[fj]
                takes[#takes + 1] = o.min == o.max and sfmt("%d", o.min) or sfmt("%d..%d", o.min, o.max)
            end
            last = n .. " data bytes; " .. fr.ident .. " (" .. rw .. ") takes " .. table.concat(takes, " or ")
        else
            local values, err = decode_form(form, fr.data)
            if values then
                msg.form, msg.values = form, values
                return msg
            end
            last = fr.ident .. ": " .. err
        end
    end
    msg.error = last
    return msg
end

local function contains(list, x)
    for _, v in ipairs(list) do
        if v == x then return true end
    end
    return false
end

-- guess_dialects: dialects ranked by what the frame alone says (its identifier in the catalog 4,
-- its header among the dialect's 2, its host side among the dialect's host addresses 1); ties
-- keep the catalog's order.
local function guess_dialects(fr)
    local ranked = {}
    for i, name in ipairs(GEN.dialect_order) do
        local d = GEN.dialects[name]
        local score = (d.commands[fr.ident] and 4 or 0) + (contains(d.headers, fr.header) and 2 or 0)
        local host, fits = 0, true
        for _, a in ipairs({ fr.src, fr.dst }) do
            if a == "U" or a == "P" then
                host = host + 1
                if not d.hosts:find(a, 1, true) then fits = false end
            end
        end
        if host > 0 and fits then score = score + 1 end
        ranked[#ranked + 1] = { name = name, score = score, at = i }
    end
    table.sort(ranked, function(x, y)
        if x.score ~= y.score then return x.score > y.score end
        return x.at < y.at
    end)
    local out = {}
    for _, r in ipairs(ranked) do out[#out + 1] = { name = r.name } end
    return out
end

-- decode_any: `prefer` ({ name, variant }) first, then the others as guess_dialects ranks them;
-- the first that names the fields wins. When none does, the first one's message, with every
-- reason. `msg.tried` lists the dialects tried before the one that decoded it.
local function decode_any(fr, prefer)
    local order = guess_dialects(fr)
    if prefer then
        local first = { prefer }
        for _, d in ipairs(order) do
            if d.name ~= prefer.name then first[#first + 1] = d end
        end
        order = first
    end
    local msgs = {}
    for _, d in ipairs(order) do
        local msg = decode_in(d, fr)
        if msg.values then
            msg.tried = {}
            for _, m in ipairs(msgs) do msg.tried[#msg.tried + 1] = m.dialect end
            return msg
        end
        msgs[#msgs + 1] = msg
    end
    local head = msgs[1]
    if #msgs > 1 then
        local others = {}
        for k = 2, #msgs do others[#others + 1] = msgs[k].dialect .. ": " .. msgs[k].error end
        head.error = head.error .. " (also tried " .. table.concat(others, "; ") .. ")"
    end
    head.tried = {}
    return head
end

-- The dialect a documented port implies ("udp"/"tcp", ports in order), and that port.
local function port_dialect(transport, ports)
    local table_ = GEN.ports[transport] or {}
    for _, port in ipairs(ports) do
        if table_[port] then return table_[port], port end
    end
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

-- recover() for the headers whose frames it applies to (#TP, #tp), the frame found appended to
-- out; false when there is none (or another header), nil as recover() says.
local function take_recovered(buf, i, hdr, final, out)
    if hdr ~= "TP" and hdr ~= "tp" then return false end
    local rec = recover(buf, i, final)
    if rec then out[#out + 1] = rec end
    return rec
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
                local rec = take_recovered(buf, i, hdr, true, out)
                if rec then pos = rec.b; break end
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
            local rec = take_recovered(buf, i, hdr, final, out)
            if rec == nil then return i end
            if rec then pos = rec.b; break end
            local nxt = find_hash(buf, i + 1, e)
            if nxt < 0 then nxt = e end
            out[#out + 1] = { kind = "bad_checksum", a = i, b = e }
            pos = nxt
        until true
    end
    return pos
end

-- Everything in `buf` (frames, frames with a bad checksum, bytes outside a frame) as
-- FrameParser.feed_datagram gives it; for a stream, also the offset from which bytes still to
-- come decide what follows (nil when nothing waits).
local function items_in(buf, stream)
    local out, len = {}, #buf
    local pos = scan(buf, 0, out, false)
    if stream and pos < len then return out, pos end
    if pos < len then
        local rest = scan(buf, pos, out, true)
        if rest < len then discard(buf, rest, len, out, "incomplete frame at end of stream", "truncated") end
    end
    return out, nil
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

-- Whether a payload on an undocumented port is TOP: the heuristic's test. The rule and its
-- numbers come from wire/heuristic.py (GEN.heuristic), the rule `decode --pcap` applies: after at
-- most max_leading_line_ends CR/LF bytes, a TOP header, then address letters in as many of the
-- next address_bytes bytes as the payload has. `head` is the payload's first head_bytes bytes.
local HEUR_HDR, HEUR_ADDR = {}, {}
for _, h in ipairs(GEN.heuristic.headers) do HEUR_HDR[h] = true end
for k = 1, #GEN.heuristic.address_letters do HEUR_ADDR[sbyte(GEN.heuristic.address_letters, k)] = true end

local function looks_like_top(head)
    head = head:sub(1, GEN.heuristic.head_bytes)
    local ends = #(head:match("^[\r\n]*"))
    if ends > GEN.heuristic.max_leading_line_ends then return false end
    local rest = head:sub(ends + 1)
    if not HEUR_HDR[rest:sub(1, 3)] then return false end
    for k = 4, math.min(#rest, 3 + GEN.heuristic.address_bytes) do
        if not HEUR_ADDR[sbyte(rest, k)] then return false end
    end
    return true
end

-- What the Wireshark glue below (and the tests, under every Lua version) use.
local CORE = {
    DECODE = DECODE, NULL = NULL, show = show, pyfloat = pyfloat, quote = quote,
    scan = scan, items_in = items_in, split_frame = split_frame, looks_like_top = looks_like_top,
    direction_of = direction_of, decode_in = decode_in, decode_any = decode_any,
    guess_dialects = guess_dialects, port_dialect = port_dialect,
}
