-- viewcomp's guard for mpv playing through a compensation shader (`viewcomp export-mpv
-- --guard FILE.lua`, then `mpv --script=FILE.lua ...`). mpv logs a user shader that it
-- cannot read, parse or compile as an error and goes on playing the video without it,
-- uncompensated, with exit status 0 (Debian 12's mpv 0.35 does so for `//!PARAM`). This
-- script makes that fatal: a shader file that does not exist, or any error-level message
-- of mpv's video output (vo/...: the shader parser, the GLSL compiler), logs why and quits
-- mpv with exit status 2, so a kiosk's supervisor sees a failure instead of a wrong picture.

local utils = require("mp.utils")

local function fail(why)
    mp.msg.error("viewcomp: " .. why .. "; the compensation shader is not applied, so mpv "
                 .. "stops (exit status 2); fix the shader or the mpv build "
                 .. "(`viewcomp check-mpv SHADER` says what this mpv rejects)")
    mp.commandv("quit", "2")
end

mp.enable_messages("error")
mp.register_event("log-message", function(e)
    if (e.level == "error" or e.level == "fatal") and e.prefix:sub(1, 2) == "vo" then
        fail("mpv's video output reported: " .. e.prefix .. ": " .. (e.text:gsub("%s+$", "")))
    end
end)

local shaders = mp.get_property_native("glsl-shaders") or {}
if #shaders == 0 then
    fail("no --glsl-shaders given")
end
for _, path in ipairs(shaders) do
    if utils.file_info(mp.command_native({"expand-path", path})) == nil then
        fail("the shader file " .. path .. " does not exist")
    end
end
