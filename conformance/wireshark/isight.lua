-- isight.lua -- Wireshark dissector for the iSight robot <-> vision "AI Box" protocol.
--
-- Part of isight-conformance. Clause IDs in expert messages ([F1], [B3], ...) refer to
-- the project's PROTOCOL.md. Frame (big-endian):
--
--   0  2    start word     FE FE                      [F1]
--   2  2    version        00 01                      [F2]
--   4  1    transfer type  01 robot->box, 10 box->robot [F3]
--   5  1    action
--   6  1    block type
--   7  1    block count N
--   8  2    block length L (of EACH block)
--   10 2    error code
--   12 N*L  blocks
--   ..  2   check          TCP: 00 00 [F6] / UDP: CRC-16 [F7]
--
-- Written for the Wireshark Lua API of 3.x/4.x; tested with tshark 4.0 (Lua 5.2) by
-- tests/e2e/test_wireshark_dissector.py. Install and preferences: README.md next to this file.

-- bit32 (Lua 5.2, and Wireshark's shim for 5.4), BitOp "bit" (LuaJIT / Wireshark 1.x-3.x),
-- else the native operators of Lua 5.3+ (compiled with load() so 5.1/5.2 never parse them).
local bit = bit32 or bit or load([[return {
    band = function(a, b) return a & b end,
    bor = function(a, b) return a | b end,
    bxor = function(a, b) return a ~ b end,
    lshift = function(a, n) return (a << n) & 0xFFFFFFFF end,
    rshift = function(a, n) return (a & 0xFFFFFFFF) >> n end,
}]])()
local band, bor, bxor, lshift, rshift = bit.band, bit.bor, bit.bxor, bit.lshift, bit.rshift

local isight = Proto("isight", "iSight Robot/Vision Protocol")

---------------------------------------------------------------------------------------
-- Constants and value strings
---------------------------------------------------------------------------------------
local HEADER_LEN = 12
local CHECK_LEN = 2
local MAX_BLOCKS = 255
local POSE_LEN, TOL_LEN, VALUE_LEN = 25, 5, 5
local MAX_FRAME_LEN = HEADER_LEN + MAX_BLOCKS * POSE_LEN + CHECK_LEN  -- 6389

local TT_ROBOT_TO_BOX, TT_BOX_TO_ROBOT = 0x01, 0x10

local vs_transfer_type = {
    [TT_ROBOT_TO_BOX] = "Robot→Box",
    [TT_BOX_TO_ROBOT] = "Box→Robot",
}

local vs_action = {
    [0x00] = "None",
    [0x01] = "CycleOn",
    [0x02] = "CycleOff",
    [0x23] = "Pose",
    [0x24] = "RegisterPose",
    [0x25] = "Tolerance",
    [0x26] = "ProgIdx",
    [0x27] = "VisionResult",
}

local BT_EMPTY, BT_POSE, BT_TOL, BT_VALUE = 0x00, 0x01, 0x02, 0x03
local vs_block_type = {
    [BT_EMPTY] = "Empty",
    [BT_POSE]  = "Pose",
    [BT_TOL]   = "Tolerance",
    [BT_VALUE] = "Int32 value",
}

local BLOCK_TYPE_LEN = { [BT_EMPTY] = 0, [BT_POSE] = POSE_LEN, [BT_TOL] = TOL_LEN, [BT_VALUE] = VALUE_LEN }
local BLOCK_TYPE_CLAUSE = { [BT_POSE] = "B1", [BT_TOL] = "B2", [BT_VALUE] = "E1" }

local vs_error_code = {
    [0x0000] = "OK",
    [0x0001] = "Box not ready (CycleOn)",
    [0x0002] = "CycleOff failed",
    [0x1001] = "Pose error",
    [0x1002] = "Tolerance error",
}

-- E3 ResultCode of a vision result answer (action 27)
local vs_result_code = {
    [0]   = "empty (robot's initial value, never sent)",
    [1]   = "OK",
    [2]   = "NG",
    [10]  = "OK, non-vision fault",
    [20]  = "NG, non-vision fault",
    [202] = "accepted, not finished (busy)",
    [400] = "request not understood",
    [404] = "no answer (robot-side timeout value, never sent)",
    [409] = "resource conflict / not ready",
}

---------------------------------------------------------------------------------------
-- CRC-16: generic parametrised (Rocksoft model). The predefined list mirrors
-- crcmod.predefined (the names are crcmod's) -- crcmod stores init XOR xorout, the
-- values here are the register init of the CRC catalogue.
---------------------------------------------------------------------------------------
local crc_algorithms = {
    -- crcmod name       poly    init    refin  refout xorout  catalogue name         check("123456789")
    { "modbus",          0x8005, 0xFFFF, true,  true,  0x0000, "CRC-16/MODBUS" },      -- 0x4B37
    { "xmodem",          0x1021, 0x0000, false, false, 0x0000, "CRC-16/XMODEM" },      -- 0x31C3
    { "kermit",          0x1021, 0x0000, true,  true,  0x0000, "CRC-16/KERMIT" },      -- 0x2189
    { "crc-16",          0x8005, 0x0000, true,  true,  0x0000, "CRC-16/ARC" },         -- 0xBB3D
    { "x-25",            0x1021, 0xFFFF, true,  true,  0xFFFF, "CRC-16/X-25" },        -- 0x906E
    { "crc-ccitt-false", 0x1021, 0xFFFF, false, false, 0x0000, "CRC-16/CCITT-FALSE" }, -- 0x29B1
    { "crc-16-usb",      0x8005, 0xFFFF, true,  true,  0xFFFF, "CRC-16/USB" },         -- 0xB4C8
    { "crc-16-buypass",  0x8005, 0x0000, false, false, 0x0000, "CRC-16/BUYPASS" },     -- 0xFEE8
    { "crc-16-dds-110",  0x8005, 0x800D, false, false, 0x0000, "CRC-16/DDS-110" },     -- 0x9ECF
    { "crc-16-dect",     0x0589, 0x0000, false, false, 0x0001, "CRC-16/DECT-R" },      -- 0x007E
    { "crc-16-dnp",      0x3D65, 0x0000, true,  true,  0xFFFF, "CRC-16/DNP" },         -- 0xEA82
    { "crc-16-en-13757", 0x3D65, 0x0000, false, false, 0xFFFF, "CRC-16/EN-13757" },    -- 0xC2B7
    { "crc-16-genibus",  0x1021, 0xFFFF, false, false, 0xFFFF, "CRC-16/GENIBUS" },     -- 0xD64E
    { "crc-16-maxim",    0x8005, 0x0000, true,  true,  0xFFFF, "CRC-16/MAXIM" },       -- 0x44C2
    { "crc-16-mcrf4xx",  0x1021, 0xFFFF, true,  true,  0x0000, "CRC-16/MCRF4XX" },     -- 0x6F91
    { "crc-16-riello",   0x1021, 0xB2AA, true,  true,  0x0000, "CRC-16/RIELLO" },      -- 0x63D0
    { "crc-16-t10-dif",  0x8BB7, 0x0000, false, false, 0x0000, "CRC-16/T10-DIF" },     -- 0xD0DB
    { "crc-16-teledisk", 0xA097, 0x0000, false, false, 0x0000, "CRC-16/TELEDISK" },    -- 0x0FB3
    { "crc-aug-ccitt",   0x1021, 0x1D0F, false, false, 0x0000, "CRC-16/AUG-CCITT" },   -- 0xE5CC
    { "custom",          nil,    nil,    nil,   nil,   nil,    "Custom (crc_custom_* preferences)" },
}
local CRC_CUSTOM = #crc_algorithms

-- Pref.enum entries are { name, description, value }; "-o" accepts either string.
local crc_enum = {}
for i, a in ipairs(crc_algorithms) do
    crc_enum[i] = { a[1], a[7], i }
end

local function reflect(v, width)
    local r = 0
    for _ = 1, width do
        r = bor(lshift(r, 1), band(v, 1))
        v = rshift(v, 1)
    end
    return r
end

-- Build a byte-at-a-time table for (poly, refin) and return a crc(string) function.
local crc_cache = {}
local function crc16_function(poly, init, refin, refout, xorout)
    local key = table.concat({ poly, init, tostring(refin), tostring(refout), xorout }, ":")
    if crc_cache[key] then return crc_cache[key] end
    local fn
    if refin == refout then
        local tbl = {}
        if refin then
            local rpoly = reflect(poly, 16)
            for b = 0, 255 do
                local c = b
                for _ = 1, 8 do
                    if band(c, 1) ~= 0 then c = bxor(rshift(c, 1), rpoly) else c = rshift(c, 1) end
                end
                tbl[b] = c
            end
            local rinit = reflect(init, 16)
            fn = function(s)
                local crc = rinit
                for i = 1, #s do
                    crc = bxor(rshift(crc, 8), tbl[band(bxor(crc, s:byte(i)), 0xFF)])
                end
                return bxor(crc, xorout)
            end
        else
            for b = 0, 255 do
                local c = lshift(b, 8)
                for _ = 1, 8 do
                    if band(c, 0x8000) ~= 0 then c = band(bxor(lshift(c, 1), poly), 0xFFFF)
                    else c = band(lshift(c, 1), 0xFFFF) end
                end
                tbl[b] = c
            end
            fn = function(s)
                local crc = init
                for i = 1, #s do
                    crc = bxor(band(lshift(crc, 8), 0xFFFF), tbl[bxor(rshift(crc, 8), s:byte(i))])
                end
                return bxor(crc, xorout)
            end
        end
    else
        -- refin ~= refout: plain bit-by-bit model
        fn = function(s)
            local crc = init
            for i = 1, #s do
                local b = s:byte(i)
                if refin then b = reflect(b, 8) end
                crc = bxor(crc, lshift(b, 8))
                for _ = 1, 8 do
                    if band(crc, 0x8000) ~= 0 then crc = band(bxor(lshift(crc, 1), poly), 0xFFFF)
                    else crc = band(lshift(crc, 1), 0xFFFF) end
                end
            end
            if refout then crc = reflect(crc, 16) end
            return bxor(crc, xorout)
        end
    end
    crc_cache[key] = fn
    return fn
end

---------------------------------------------------------------------------------------
-- Preferences
---------------------------------------------------------------------------------------
local DEFAULT_PORT = 9004
isight.prefs.tcp_port = Pref.uint("TCP port", DEFAULT_PORT,
    "TCP port of the AI Box (server). Frames sent to it are Robot→Box.")
isight.prefs.tcp_port_extra = Pref.uint("Extra TCP port", 0,
    "A second TCP port to decode as iSight (0 = none)")
isight.prefs.udp_port = Pref.uint("UDP port", DEFAULT_PORT,
    "UDP port to decode as iSight (0 = none; the heuristic still finds frames on any port)")
isight.prefs.crc_algorithm = Pref.enum("UDP CRC algorithm", 1,
    "CRC-16 algorithm of the UDP check field. On the command line use the crcmod.predefined "
    .. "name (modbus, xmodem, kermit, crc-16, x-25, crc-ccitt-false, crc-16-usb, ...) or the "
    .. "catalogue name shown here; 'custom' uses the crc_custom_* preferences", crc_enum, false)
isight.prefs.crc_byte_order = Pref.enum("UDP CRC byte order", 1,
    "Byte order of the CRC in the check field",
    { { "big", "big", 1 }, { "little", "little", 2 } }, true)
-- hex-friendly strings: Pref.uint is decimal-only in the Lua API
isight.prefs.crc_custom_poly = Pref.string("Custom CRC polynomial", "0x8005",
    "Custom CRC-16: polynomial in hex (0x prefix optional), normal form without the x^16 term")
isight.prefs.crc_custom_init = Pref.string("Custom CRC init", "0xFFFF",
    "Custom CRC-16: initial register value in hex (unreflected, as in the CRC catalogue)")
isight.prefs.crc_custom_refin = Pref.bool("Custom CRC reflect input", true,
    "Custom CRC-16: reflect each input byte")
isight.prefs.crc_custom_refout = Pref.bool("Custom CRC reflect output", true,
    "Custom CRC-16: reflect the final register")
isight.prefs.crc_custom_xorout = Pref.string("Custom CRC xorout", "0x0000",
    "Custom CRC-16: value XORed into the final register, in hex")
isight.prefs.first_index = Pref.uint("First block index", 0,
    "Index of the first data block (B3: 0 by the normative text, 1 by the revision's diagram)")

local function current_crc()
    local idx = isight.prefs.crc_algorithm
    local a = crc_algorithms[idx] or crc_algorithms[1]
    if idx == CRC_CUSTOM then
        local p = isight.prefs
        local function num(v) return band(tonumber((tostring(v):gsub("^%s*0[xX]", "")), 16) or 0, 0xFFFF) end
        return "custom", crc16_function(num(p.crc_custom_poly), num(p.crc_custom_init),
            p.crc_custom_refin, p.crc_custom_refout, num(p.crc_custom_xorout))
    end
    return a[1], crc16_function(a[2], a[3], a[4], a[5], a[6])
end

---------------------------------------------------------------------------------------
-- Fields
---------------------------------------------------------------------------------------
local f = {
    start_word    = ProtoField.uint16("isight.start_word", "Start word", base.HEX),
    version       = ProtoField.uint16("isight.version", "Version", base.HEX),
    transfer_type = ProtoField.uint8("isight.transfer_type", "Transfer type", base.HEX, vs_transfer_type),
    action        = ProtoField.uint8("isight.action", "Action", base.HEX, vs_action),
    block_type    = ProtoField.uint8("isight.block_type", "Block type", base.HEX, vs_block_type),
    block_count   = ProtoField.uint8("isight.block_count", "Block count", base.DEC),
    block_length  = ProtoField.uint16("isight.block_length", "Block length", base.DEC),
    error_code    = ProtoField.uint16("isight.error_code", "Error code", base.HEX, vs_error_code),
    check         = ProtoField.uint16("isight.check", "Check", base.HEX),
    crc_status    = ProtoField.string("isight.crc_status", "CRC status"),
    crc_computed  = ProtoField.uint16("isight.crc_computed", "Computed CRC", base.HEX),
    crc_algorithm = ProtoField.string("isight.crc_algorithm", "CRC algorithm"),
    frame_length  = ProtoField.uint32("isight.frame_length", "Frame length", base.DEC),
    block         = ProtoField.none("isight.block", "Block"),
    block_index   = ProtoField.uint8("isight.block.index", "Index", base.DEC),
    block_data    = ProtoField.bytes("isight.block.data", "Data"),
    pose_x        = ProtoField.float("isight.pose.x", "X"),
    pose_y        = ProtoField.float("isight.pose.y", "Y"),
    pose_z        = ProtoField.float("isight.pose.z", "Z"),
    pose_w        = ProtoField.float("isight.pose.w", "W"),
    pose_p        = ProtoField.float("isight.pose.p", "P"),
    pose_r        = ProtoField.float("isight.pose.r", "R"),
    tolerance     = ProtoField.float("isight.tolerance", "Tolerance"),
    value         = ProtoField.int32("isight.value", "Value", base.DEC),
    trailing      = ProtoField.bytes("isight.trailing", "Trailing bytes"),
}
isight.fields = {
    f.start_word, f.version, f.transfer_type, f.action, f.block_type, f.block_count,
    f.block_length, f.error_code, f.check, f.crc_status, f.crc_computed, f.crc_algorithm,
    f.frame_length, f.block, f.block_index, f.block_data, f.pose_x, f.pose_y, f.pose_z,
    f.pose_w, f.pose_p, f.pose_r, f.tolerance, f.value, f.trailing,
}
local pose_fields = { f.pose_x, f.pose_y, f.pose_z, f.pose_w, f.pose_p, f.pose_r }
local pose_names = { "x", "y", "z", "w", "p", "r" }

local ef = {
    malformed = ProtoExpert.new("isight.malformed", "Malformed iSight frame",
        expert.group.MALFORMED, expert.severity.ERROR),
    protocol  = ProtoExpert.new("isight.protocol", "iSight protocol violation",
        expert.group.PROTOCOL, expert.severity.ERROR),
    warning   = ProtoExpert.new("isight.warning", "iSight SHOULD-level deviation",
        expert.group.PROTOCOL, expert.severity.WARN),
    bad_crc   = ProtoExpert.new("isight.bad_crc", "Bad iSight CRC",
        expert.group.CHECKSUM, expert.severity.ERROR),
    error_code = ProtoExpert.new("isight.error_code.nonzero", "Non-zero iSight error code",
        expert.group.RESPONSE_CODE, expert.severity.NOTE),
}
isight.experts = { ef.malformed, ef.protocol, ef.warning, ef.bad_crc, ef.error_code }

---------------------------------------------------------------------------------------
-- Helpers
---------------------------------------------------------------------------------------
local function hex(v, digits) return string.format("0x%0" .. (digits or 2) .. "X", v) end

local function is_server_port(port, transport)
    local p = isight.prefs
    if port == 0 then return false end
    if transport == "udp" then return port == p.udp_port end
    return port == p.tcp_port or port == p.tcp_port_extra
end

-- Direction expected from the ports: 0x01 if sent to the server port, 0x10 if sent
-- from it, nil when unknown (heuristic on an unconfigured port, or both ends equal).
local function expected_transfer_type(pinfo, transport)
    local to_srv = is_server_port(pinfo.dst_port, transport)
    local from_srv = is_server_port(pinfo.src_port, transport)
    if to_srv and not from_srv then return TT_ROBOT_TO_BOX end
    if from_srv and not to_srv then return TT_BOX_TO_ROBOT end
    return nil
end

-- The block layout B5/A2/E2/E3 require for (transfer type, action):
-- returns type, exact count (or nil), minimum count, length, clause
local function required_layout(tt, action)
    local answer = (tt == TT_BOX_TO_ROBOT)
    if action == 0x26 then return BT_VALUE, 1, 1, VALUE_LEN, "E2" end
    if action == 0x27 then
        if answer then return BT_VALUE, 1, 1, VALUE_LEN, "E3" end
        return BT_EMPTY, 0, 0, 0, "E3"
    end
    if answer then return BT_EMPTY, 0, 0, 0, "A2" end
    if action == 0x23 or action == 0x24 then return BT_POSE, nil, 1, POSE_LEN, "B5" end
    if action == 0x25 then return BT_TOL, nil, 1, TOL_LEN, "B5" end
    return BT_EMPTY, 0, 0, 0, "B5" -- 00, 01, 02
end

local function is_finite(x) return x == x and x ~= math.huge and x ~= -math.huge end

---------------------------------------------------------------------------------------
-- One frame. tvb holds exactly the frame bytes available (for TCP exactly one frame,
-- for UDP the whole datagram). Returns the Info text for the frame.
---------------------------------------------------------------------------------------
local function dissect_frame(tvb, pinfo, tree, transport)
    local len = tvb:len()
    local item = tree:add(isight, tvb(), "iSight " .. (transport == "udp" and "UDP" or "TCP") .. " frame")
    local errors, warnings = 0, 0
    local function bad(expert_field, target, text)
        if expert_field == ef.warning then warnings = warnings + 1 else errors = errors + 1 end
        target:add_proto_expert_info(expert_field, text)
    end

    if len < HEADER_LEN then
        bad(ef.malformed, item, string.format("[F5] %d bytes, shorter than the %d-byte header", len, HEADER_LEN))
        return "iSight (truncated)"
    end

    local start_word = tvb(0, 2):uint()
    local version = tvb(2, 2):uint()
    local tt = tvb(4, 1):uint()
    local action = tvb(5, 1):uint()
    local btype = tvb(6, 1):uint()
    local n = tvb(7, 1):uint()
    local l = tvb(8, 2):uint()
    local err = tvb(10, 2):uint()
    local blocks_len = n * l
    local frame_len = HEADER_LEN + blocks_len + CHECK_LEN

    local it = item:add(f.start_word, tvb(0, 2))
    if start_word ~= 0xFEFE then
        bad(ef.malformed, it, string.format("[F1] start word %s, expected 0xFEFE", hex(start_word, 4)))
    end
    it = item:add(f.version, tvb(2, 2))
    if version ~= 0x0001 then
        bad(ef.malformed, it, string.format("[F2] version %s, expected 0x0001", hex(version, 4)))
    end
    it = item:add(f.transfer_type, tvb(4, 1))
    local want_tt = expected_transfer_type(pinfo, transport)
    if tt ~= TT_ROBOT_TO_BOX and tt ~= TT_BOX_TO_ROBOT then
        bad(ef.malformed, it, string.format("[F3] transfer type %s, expected 0x01 (robot→box) or 0x10 (box→robot)", hex(tt)))
    elseif want_tt and tt ~= want_tt then
        bad(ef.protocol, it, string.format("[F3] transfer type %s on a %s frame (by port), expected %s",
            hex(tt), vs_transfer_type[want_tt], hex(want_tt)))
    end
    it = item:add(f.action, tvb(5, 1))
    if vs_action[action] == nil then
        bad(ef.protocol, it, string.format("[A5] unknown action %s", hex(action)))
    end
    local it_type = item:add(f.block_type, tvb(6, 1))
    local it_count = item:add(f.block_count, tvb(7, 1))
    local it_len = item:add(f.block_length, tvb(8, 2))
    it = item:add(f.error_code, tvb(10, 2))
    if err ~= 0 then
        if vs_error_code[err] == nil then
            bad(ef.warning, it, string.format("[A3] unknown error code %s", hex(err, 4)))
        else
            it:add_proto_expert_info(ef.error_code, string.format("[A3] error code %s (%s)", hex(err, 4), vs_error_code[err]))
        end
    end
    item:add(f.frame_length, frame_len):set_generated()
    if action == 0x00 and tt == TT_BOX_TO_ROBOT and err ~= 0 then
        bad(ef.protocol, it, string.format("[A4] answer to action 0x00 with error code %s, expected 0x0000", hex(err, 4)))
    end

    -- B5 / A2 / E2 / E3: layout required by the action
    if vs_action[action] ~= nil then
        local rtype, rcount, rmin, rlen, clause = required_layout(tt, action)
        local aname = vs_action[action]
        if btype ~= rtype then
            bad(ef.protocol, it_type, string.format("[%s] block type %s with action %s (%s), expected %s",
                clause, hex(btype), hex(action), aname, hex(rtype)))
        end
        if rcount and n ~= rcount then
            bad(ef.protocol, it_count, string.format("[%s] block count %d with action %s (%s), expected %d",
                clause, n, hex(action), aname, rcount))
        elseif n < rmin then
            bad(ef.protocol, it_count, string.format("[%s] block count %d with action %s (%s), expected at least %d",
                clause, n, hex(action), aname, rmin))
        end
        if l ~= rlen then
            bad(ef.protocol, it_len, string.format("[%s] block length %d with action %s (%s), expected %d",
                clause, l, hex(action), aname, rlen))
        end
    end
    -- the block type itself fixes the length (B1, B2, E1)
    local type_len = BLOCK_TYPE_LEN[btype]
    if type_len == nil then
        bad(ef.protocol, it_type, string.format("[B5] unknown block type %s", hex(btype)))
    elseif n > 0 and l ~= type_len then
        bad(ef.protocol, it_len, string.format("[%s] block length %d for block type %s, expected %d",
            BLOCK_TYPE_CLAUSE[btype] or "B5", l, hex(btype), type_len))
    elseif btype == BT_EMPTY and (n ~= 0 or l ~= 0) then
        bad(ef.protocol, it_count, string.format("[B5] empty block type with N=%d, L=%d, expected 0, 0", n, l))
    end

    -- Blocks
    local info_extra = {}
    local first_index = isight.prefs.first_index
    local avail_blocks = math.min(blocks_len, len - HEADER_LEN)
    if l > 0 then
        for i = 0, n - 1 do
            local off = HEADER_LEN + i * l
            if off >= HEADER_LEN + avail_blocks then break end
            local blen = math.min(l, HEADER_LEN + avail_blocks - off)
            local btree = item:add(f.block, tvb(off, blen))
            btree:set_text(string.format("Block %d", i))
            local idx = tvb(off, 1):uint()
            local iit = btree:add(f.block_index, tvb(off, 1))
            if idx ~= first_index + i then
                bad(ef.protocol, iit, string.format("[B3] block index %d, expected %d", idx, first_index + i))
            end
            if blen < l then
                bad(ef.malformed, btree, string.format("[F5] block %d truncated: %d of %d bytes", i, blen, l))
                if blen > 1 then btree:add(f.block_data, tvb(off + 1, blen - 1)) end
            elseif btype == BT_POSE and l == POSE_LEN then
                local vals = {}
                for k = 1, 6 do
                    local r = tvb(off + 1 + (k - 1) * 4, 4)
                    local v = r:float()
                    local fit = btree:add(pose_fields[k], r)
                    vals[k] = string.format("%g", v)
                    if not is_finite(v) then
                        bad(ef.warning, fit, string.format("[B4] pose.%s of block %d is %s", pose_names[k], i, tostring(v)))
                    end
                end
                btree:append_text(string.format(": index %d (%s)", idx, table.concat(vals, ", ")))
            elseif btype == BT_TOL and l == TOL_LEN then
                local v = tvb(off + 1, 4):float()
                local fit = btree:add(f.tolerance, tvb(off + 1, 4))
                btree:append_text(string.format(": index %d, tolerance %g", idx, v))
                if not is_finite(v) then
                    bad(ef.warning, fit, string.format("[B4] tolerance of block %d is %s", i, tostring(v)))
                end
            elseif btype == BT_VALUE and l == VALUE_LEN then
                local v = tvb(off + 1, 4):int()
                local vit = btree:add(f.value, tvb(off + 1, 4))
                btree:append_text(string.format(": index %d, value %d", idx, v))
                if action == 0x27 and tt == TT_BOX_TO_ROBOT then
                    local rc = vs_result_code[v]
                    vit:append_text(" (ResultCode: " .. (rc or "unknown") .. ")")
                    info_extra[#info_extra + 1] = string.format("result=%d", v)
                    if rc == nil then
                        bad(ef.warning, vit, string.format("[E3] unknown ResultCode %d", v))
                    elseif v == 0 or v == 404 then
                        bad(ef.protocol, vit, string.format("[E3] ResultCode %d is never sent by the box", v))
                    end
                elseif action == 0x26 and tt == TT_BOX_TO_ROBOT and v == 409 then
                    vit:append_text(" (409: resource conflict / not ready)")
                    info_extra[#info_extra + 1] = "value=409"
                else
                    info_extra[#info_extra + 1] = string.format("value=%d", v)
                end
            elseif blen > 1 then
                btree:add(f.block_data, tvb(off + 1, blen - 1))
            end
        end
    end

    -- Check field
    local check_off = HEADER_LEN + blocks_len
    if transport == "udp" then
        if len ~= frame_len then
            bad(ef.malformed, item, string.format(
                "[F5][F7] datagram is %d bytes, the header announces a %d-byte frame (12 + %d×%d + 2)",
                len, frame_len, n, l))
        end
        if len >= frame_len then
            local alg, crcfn = current_crc()
            local little = (isight.prefs.crc_byte_order == 2)
            local cr = tvb(check_off, 2)
            -- isight.check is the value on the wire read big-endian, like every field (F4);
            -- the CRC is compared in the configured byte order.
            local cit = item:add(f.check, cr)
            local received = little and cr:le_uint() or cr:uint()
            local computed = crcfn(tvb:raw(0, check_off))
            local order = little and "little-endian" or "big-endian"
            cit:append_text(string.format(" [%s %s]", order, hex(received, 4)))
            local good = (received == computed)
            item:add(f.crc_status, good and "good" or "bad"):set_generated()
            item:add(f.crc_computed, computed):set_generated()
            item:add(f.crc_algorithm, alg .. " (" .. order .. ")"):set_generated()
            if not good then
                bad(ef.bad_crc, cit, string.format("[F7] bad CRC: received %s, computed %s (%s, %s)",
                    hex(received, 4), hex(computed, 4), alg, order))
            end
            if len > frame_len then
                item:add(f.trailing, tvb(frame_len, len - frame_len))
            end
        end
    else
        if len >= frame_len then
            local cr = tvb(check_off, 2)
            local cit = item:add(f.check, cr)
            local check = cr:uint()
            if check ~= 0 then
                local alg, crcfn = current_crc()
                local note = ""
                local computed = crcfn(tvb:raw(0, check_off))
                if computed == check then note = string.format(" (it is the %s CRC of the frame)", alg) end
                bad(ef.warning, cit, string.format("[F6] check field over TCP is %s, a sender MUST send 0x0000%s",
                    hex(check, 4), note))
            end
        elseif frame_len > MAX_FRAME_LEN then
            bad(ef.malformed, item, string.format(
                "[R5] header announces %d blocks × %d bytes = a %d-byte frame; the largest legal frame is %d bytes (not reassembled)",
                n, l, frame_len, MAX_FRAME_LEN))
        else
            bad(ef.malformed, item, string.format("[F5] frame truncated: %d of %d bytes", len, frame_len))
        end
    end

    -- Info / summary
    local dir = vs_transfer_type[tt] or ("TT=" .. hex(tt))
    local aname = vs_action[action] or ("Action " .. hex(action))
    local info = dir .. " " .. aname
    if #info_extra > 0 then info = info .. " " .. table.concat(info_extra, " ") end
    if err ~= 0 then info = info .. " err=" .. hex(err, 4) end
    if n > 0 and btype ~= BT_VALUE then info = info .. string.format(" [%d block%s]", n, n == 1 and "" or "s") end
    if errors > 0 then info = info .. " [MALFORMED]" elseif warnings > 0 then info = info .. " [WARNING]" end
    item:append_text(string.format(", %s, %d bytes", info, frame_len))
    return info
end

---------------------------------------------------------------------------------------
-- Transports
---------------------------------------------------------------------------------------
local function set_columns(pinfo, infos)
    if #infos == 0 then return end
    pinfo.cols.protocol = "iSight"
    pinfo.cols.info = table.concat(infos, " | ")
end

local START_PATTERN = "\254\254\000\001" -- FE FE 00 01

-- offset of the next FE FE 00 01 at or after `from`, or nil
local function find_next_start(tvb, from)
    if from >= tvb:len() then return nil end
    local pos = string.find(tvb:raw(from), START_PATTERN, 1, true)
    return pos and (from + pos - 1) or nil
end

-- TCP: frames are delimited by the header; reassemble across segments, several per segment.
local function dissect_tcp(tvb, pinfo, tree)
    local len = tvb:len()
    local offset = 0
    local infos = {}
    local function need_more(bytes)
        pinfo.desegment_offset = offset
        pinfo.desegment_len = bytes
        set_columns(pinfo, infos)
        return len
    end
    while offset < len do
        local remaining = len - offset
        local frame_len = nil
        if remaining >= HEADER_LEN then
            frame_len = HEADER_LEN + tvb(offset + 7, 1):uint() * tvb(offset + 8, 2):uint() + CHECK_LEN
        end
        -- R6: bytes that do not start with the start word. If FE FE 00 01 follows in what
        -- we have, and not exactly where this "header" says its frame ends (that would be
        -- a frame with a damaged start word, dissected as such), skip to it as garbage.
        local garbage = 0
        if remaining >= 2 and tvb(offset, 2):uint() ~= 0xFEFE then
            local next_start = find_next_start(tvb, offset + 1)
            if next_start and next_start - offset ~= frame_len then
                garbage = next_start - offset
            end
        end
        if garbage > 0 then
            local item = tree:add(isight, tvb(offset, garbage), "iSight garbage")
            item:add_proto_expert_info(ef.malformed, string.format(
                "[F1] %d bytes without a start word before the next FE FE 00 01 (skipped, R6)", garbage))
            infos[#infos + 1] = string.format("%d bytes of garbage [MALFORMED]", garbage)
            offset = offset + garbage
        elseif frame_len == nil then
            return need_more(DESEGMENT_ONE_MORE_SEGMENT)
        elseif tvb(offset + 2, 2):uint() ~= 0x0001 then
            -- F2/R6: a header whose version is not 00 01 is not trusted for framing (the
            -- codec's stream decoder and the reference box skip to the next start word too)
            local version = tvb(offset + 2, 2):uint()
            local next_start = find_next_start(tvb, offset + 2)
            local skip = next_start and (next_start - offset) or remaining
            local item = tree:add(isight, tvb(offset, skip), "iSight header with an unknown version")
            item:add(f.start_word, tvb(offset, 2))
            item:add(f.version, tvb(offset + 2, 2))
            item:add_proto_expert_info(ef.malformed, string.format(
                "[F2] version %s, expected 0x0001: %d bytes skipped to the next FE FE 00 01 (R6)", hex(version, 4), skip))
            infos[#infos + 1] = string.format("version %s, %d bytes skipped [MALFORMED]", hex(version, 4), skip)
            offset = offset + skip
        elseif frame_len > MAX_FRAME_LEN then
            -- R5: never wait for an impossible frame; show what is there as malformed.
            infos[#infos + 1] = dissect_frame(tvb(offset, remaining):tvb(), pinfo, tree, "tcp")
            set_columns(pinfo, infos)
            return len
        elseif remaining < frame_len then
            return need_more(frame_len - remaining)
        else
            infos[#infos + 1] = dissect_frame(tvb(offset, frame_len):tvb(), pinfo, tree, "tcp")
            offset = offset + frame_len
        end
    end
    set_columns(pinfo, infos)
    return offset
end

local function dissect_udp(tvb, pinfo, tree)
    set_columns(pinfo, { dissect_frame(tvb, pinfo, tree, "udp") })
    return tvb:len()
end

-- pinfo.port_type is PT_TCP (2) or PT_UDP (3) for the layer that called us (epan's
-- port_type enum, stable since 1.x).
local PT_UDP = 3

function isight.dissector(tvb, pinfo, tree)
    if pinfo.port_type == PT_UDP then
        return dissect_udp(tvb, pinfo, tree)
    end
    return dissect_tcp(tvb, pinfo, tree)
end

local function looks_like_isight(tvb)
    if tvb:len() < 5 then return false end
    if tvb(0, 2):uint() ~= 0xFEFE or tvb(2, 2):uint() ~= 0x0001 then return false end
    local tt = tvb(4, 1):uint()
    return tt == TT_ROBOT_TO_BOX or tt == TT_BOX_TO_ROBOT
end

local function heur_tcp(tvb, pinfo, tree)
    if not looks_like_isight(tvb) then return false end
    -- the rest of this TCP conversation (continuation segments) goes to us directly
    pinfo.conversation = isight
    dissect_tcp(tvb, pinfo, tree)
    return true
end

local function heur_udp(tvb, pinfo, tree)
    if not looks_like_isight(tvb) then return false end
    dissect_udp(tvb, pinfo, tree)
    return true
end

---------------------------------------------------------------------------------------
-- Registration
---------------------------------------------------------------------------------------
local registered = { tcp = {}, udp = {} }
local function register_ports()
    local tcp_table = DissectorTable.get("tcp.port")
    local udp_table = DissectorTable.get("udp.port")
    for _, p in ipairs(registered.tcp) do tcp_table:remove(p, isight) end
    for _, p in ipairs(registered.udp) do udp_table:remove(p, isight) end
    registered = { tcp = {}, udp = {} }
    for _, p in ipairs({ isight.prefs.tcp_port, isight.prefs.tcp_port_extra }) do
        if p ~= 0 then tcp_table:add(p, isight); registered.tcp[#registered.tcp + 1] = p end
    end
    if isight.prefs.udp_port ~= 0 then
        udp_table:add(isight.prefs.udp_port, isight)
        registered.udp[1] = isight.prefs.udp_port
    end
end

function isight.prefs_changed()
    register_ports()
end

register_ports()
isight:register_heuristic("tcp", heur_tcp)
isight:register_heuristic("udp", heur_udp)
