-- A minimal stand-in for the part of Wireshark's Lua API that topgimbal.lua uses: enough to load
-- the generated dissector under a plain Lua (5.2, 5.3, 5.4) and run it on a datagram, recording
-- the tree it builds, its expert infos and its columns. Not Wireshark: the tests compare what it
-- records with tshark (real Wireshark 4.0, Lua 5.2) and across Lua versions.

SHIM = { protos = {}, tables = {}, heuristics = {} }

ProtoField = setmetatable({}, {
    __index = function(_, kind)
        return function(abbr, name) return { abbr = abbr, kind = kind, name = name } end
    end,
})
ProtoExpert = { new = function(abbr) return { abbr = abbr } end }
local names = setmetatable({}, { __index = function(_, k) return k end })
expert = { group = names, severity = names }
base = names
Pref = {
    enum = function(_, default) return default end,
    bool = function(_, default) return default end,
}
DESEGMENT_ONE_MORE_SEGMENT = 0x0fffffff
Field = { new = function() return function() return nil end end } -- datagrams only: no tcp.* fields

function Proto(name)
    local p = { name = name, prefs = {}, fields = {}, experts = {} }
    function p.register_heuristic(_, where, fn) SHIM.heuristics[where] = fn end
    SHIM.protos[name] = p
    return p
end

DissectorTable = {
    get = function(name)
        SHIM.tables[name] = SHIM.tables[name] or {}
        return { add = function(_, port, proto) SHIM.tables[name][port] = proto end }
    end,
}

-- the tree: every item keeps the field's abbreviation, its value, its text and its expert infos
local Item = {}
Item.__index = Item

local function item(abbr, value, label)
    return setmetatable({ abbr = abbr, value = value, label = label, children = {}, experts = {} }, Item)
end

function Item:add(what, range, value, label)
    assert(type(range) == "table" and range.len ~= nil, "a tree item needs a Tvb range")
    local child
    if what.abbr then
        child = item(what.abbr, value, label)
    else -- the protocol's own subtree: its text is the third argument
        child = item(what.name, nil, value)
    end
    child.range_off, child.range_len = range.off, range.len
    self.children[#self.children + 1] = child
    return child
end

function Item:set_generated() return self end
function Item:set_text(text) self.label = text end
function Item:add_proto_expert_info(ex, text) self.experts[#self.experts + 1] = { abbr = ex.abbr, text = text } end

-- Run the dissector registered for a UDP port (or the heuristic) on `payload`.
function SHIM.dissect(payload, src_port, dst_port)
    local tvb = setmetatable({}, {
        __call = function(_, off, len) return { off = off, len = len } end,
        __index = {
            len = function() return #payload end,
            raw = function(_, off, len) return payload:sub(off + 1, off + len) end,
        },
    })
    local pinfo = {
        src_port = src_port, dst_port = dst_port, can_desegment = 0, number = 1, visited = false,
        cols = {},
    }
    local root = item("frame", nil, "")
    local proto = SHIM.tables["udp.port"][src_port] or SHIM.tables["udp.port"][dst_port]
    if proto then
        proto.dissector(tvb, pinfo, root)
    else
        SHIM.heuristics.udp(tvb, pinfo, root)
    end
    return root, pinfo.cols
end
