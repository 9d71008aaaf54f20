-- ---------------------------------------------------------------------------------------------
-- Wireshark glue (fixed): protocol fields, preferences, the tree, the Info column, TCP
-- reassembly and registration, over the pure core above. Uses only API that Wireshark 3.x to
-- 4.4 share (Proto, ProtoField, ProtoExpert, Pref, DissectorTable, Field, Tvb, Pinfo, TreeItem).
-- ---------------------------------------------------------------------------------------------

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
    dialect_tried = ProtoField.string("top.dialect.tried", "Dialect tried first"),
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

-- Preferences. The model decides first (its own dialect: the C11 counts rates in 0.5 deg/s),
-- then the dialect, then a documented port, then the frame; whatever is preferred, a frame it
-- cannot decode is tried with the other dialect (topgimbal's decode_any does the same).
local DIALECT_PREF = { { 1, "auto", 0 } }
for i, name in ipairs(GEN.dialect_order) do DIALECT_PREF[#DIALECT_PREF + 1] = { i + 1, name, i } end
top.prefs.dialect = Pref.enum("Dialect", 0,
    "auto: by documented port, else by the frame (the dialect whose catalog, headers and host "
    .. "addresses fit it best); a frame the chosen dialect cannot decode is tried with the other",
    DIALECT_PREF, false)
local MODEL_PREF = { { 1, "auto", 0 } }
for i, m in ipairs(GEN.models) do MODEL_PREF[#MODEL_PREF + 1] = { i + 1, m.name, i } end
top.prefs.model = Pref.enum("Model", 0,
    "a device model: decode with its dialect and its own options (e.g. the C11's 0.5 deg/s rate "
    .. "step); overrides Dialect and the port", MODEL_PREF, false)

local f_tcp_stream, f_tcp_seq, f_tcp_len = Field.new("tcp.stream"), Field.new("tcp.seq"), Field.new("tcp.len")

local function transport_of(pinfo)
    if f_tcp_stream() then return "tcp" end
    return "udp"
end

-- The dialect preferred for a frame, and why: { name, variant } or nil (the frame decides).
local function preferred(pinfo)
    local model = GEN.models[top.prefs.model or 0]
    if model then return { name = model.dialect, variant = model.variant }, "model preference " .. model.name end
    local forced = GEN.dialect_order[top.prefs.dialect or 0]
    if forced then return { name = forced }, "preference" end
    local by_port, port = CORE.port_dialect(transport_of(pinfo), { pinfo.src_port, pinfo.dst_port })
    if by_port then return { name = by_port }, "port " .. port end
    return nil, "frame"
end

-- -- the tree -----------------------------------------------------------------------------------

local HEADER_KIND = {
    ["#TP"] = "length as one hex character",
    ["#tp"] = "length as one hex character",
    ["#tP"] = "length as one raw byte",
    ["#Tp"] = "16-bit length, no control character",
}
local CONTROL = { r = "r (query)", w = "w (set / control)" }
local show, quote, NULL = CORE.show, CORE.quote, CORE.NULL

local function add_frame(tvb, pinfo, tree, buf, item)
    local a, b = item.a, item.b
    local fr = CORE.split_frame(buf, item)
    local prefer, why = preferred(pinfo)
    local msg = CORE.decode_any(fr, prefer)
    local fell_back = #msg.tried > 0
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
        local shown = fr.data:gsub("[^\32-\126]", function(ch) return string.format("\\x%02x", ch:byte()) end)
        sub:add(pf.data, tvb(a + 10, #fr.data), shown)
    end
    local crc_item = sub:add(pf.checksum, tvb(b - 2, 2), fr.crc,
        "Checksum: " .. fr.crc .. (ok and " [correct]" or (" [incorrect, should be " .. fr.expected .. "]")))
    crc_item:add(pf.checksum_status, tvb(b - 2, 2), ok and 1 or 0):set_generated()
    if not ok then
        crc_item:add(pf.checksum_expected, tvb(b - 2, 2), fr.expected):set_generated()
        crc_item:add_proto_expert_info(ex.bad_checksum, "Bad checksum: " .. fr.crc .. " on the wire, expected " .. fr.expected)
    end
    local variant = msg.variant and (msg.variant .. " profile, ") or ""
    local because = "by " .. why
    if fell_back then
        because = "fallback: " .. table.concat(msg.tried, ", ") .. " (by " .. why .. ") could not decode it"
    end
    sub:add(pf.dialect, tvb(a, b - a), msg.dialect, "Dialect: " .. msg.dialect .. " (" .. variant .. because .. ")")
        :set_generated()
    if fell_back then
        sub:add(pf.dialect_tried, tvb(a, b - a), table.concat(msg.tried, ",")):set_generated()
    end
    local dir = CORE.direction_of(fr.src, fr.dst)
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
    if fell_back then summary[#summary + 1] = "[" .. msg.dialect .. "]" end
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
    local stream = pinfo.can_desegment > 0
    local out, waits = CORE.items_in(buf, stream)
    if waits then
        pinfo.desegment_offset = waits
        pinfo.desegment_len = DESEGMENT_ONE_MORE_SEGMENT
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
    if not CORE.looks_like_top(tvb:raw(0, math.min(len, GEN.heuristic.head_bytes))) then return false end
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
