-- viewcomp's guard for mpv playing through a compensation shader (`viewcomp export-mpv
-- --guard FILE.lua`, then `mpv --script=FILE.lua ...`). mpv logs a user shader that it
-- cannot read, parse or compile as an error and goes on playing the video without it,
-- uncompensated, with exit status 0 (Debian 12's mpv 0.35 does so for `//!PARAM`). This
-- script makes that fatal, and tells it apart from a video output that never opened:
--
-- * the shader rejected (a missing file, or an error of mpv's video output about a shader,
--   texture, hook or GLSL): exit status 2, "the compensation shader was rejected";
-- * no video output (mpv could not create any GPU context or open its --vo: no display, no
--   driver): exit status 3, "mpv could not open a video output", with the errors mpv logged
--   while it probed the contexts. The shader was never tried: fix the display, not it.
--
-- Errors logged while mpv probes its GPU contexts (no TTY, no DRM node, no Wayland) are
-- harmless when a later context works, so they only count as context for the second failure.
-- Any other error of the video output counts as the shader's: a wrong picture is worse than
-- none.

local utils = require("mp.utils")

local me = mp.get_script_name()
local probed = {}
local done = false

local function stop(status, text)
    if done then
        return
    end
    done = true
    mp.msg.error("viewcomp: " .. text)
    mp.commandv("quit", tostring(status))
end

local function rejected(why)
    stop(2, "the compensation shader was rejected (" .. why .. "); mpv would play the video "
         .. "uncompensated, so it stops (exit status 2); fix the shader or the mpv build "
         .. "(`viewcomp check-mpv SHADER` says what this mpv rejects)")
end

local function no_output(why)
    local seen = ""
    if #probed > 0 then
        seen = "; while probing: " .. table.concat(probed, "; ")
    end
    stop(3, "mpv could not open a video output (" .. why .. seen .. "); the shader was not "
         .. "tried; fix the display or the video output (DISPLAY, --vo, --gpu-context), "
         .. "not the shader (exit status 3)")
end

local function has_any(text, words)
    local t = text:lower()
    for _, word in ipairs(words) do
        if t:find(word, 1, true) then
            return true
        end
    end
    return false
end

local SHADER_WORDS = {"shader", "texture", "hook", "glsl", "compile", "param", "uniform"}
local PROBE_WORDS = {"tty", "vt control", "drm", "kms", "gbm", "wayland", "x11", "display",
                     "egl", "gpu context", "failed to create", "failed to initialize"}

local function probing(text)
    return has_any(text, PROBE_WORDS) and not has_any(text, SHADER_WORDS)
end

local function about_output(text)
    return text:find("Failed initializing any suitable GPU context", 1, true) ~= nil
        or text:find("Error opening/initializing the selected video_out", 1, true) ~= nil
end

-- mpv runs a hook's handler before it goes on, and a script handles its events in order: by
-- the time the file is unloaded (after a video output that failed to open, say) the guard
-- has seen every message before it and asked for its exit status, which mpv's own ("errors
-- when loading file": 2) would otherwise race.
mp.add_hook("on_unload", 50, function() end)

mp.enable_messages("error")
mp.register_event("log-message", function(e)
    if e.prefix == me or (e.level ~= "error" and e.level ~= "fatal") then
        return
    end
    local text = e.text:gsub("%s+$", "")
    if about_output(text) then
        no_output(e.prefix .. ": " .. text)
    elseif e.prefix:sub(1, 2) == "vo" then
        if probing(text) then
            table.insert(probed, e.prefix .. ": " .. text)
        else
            rejected("mpv's video output reported: " .. e.prefix .. ": " .. text)
        end
    end
end)

local shaders = mp.get_property_native("glsl-shaders") or {}
if #shaders == 0 then
    rejected("no --glsl-shaders given")
end
for _, path in ipairs(shaders) do
    if utils.file_info(mp.command_native({"expand-path", path})) == nil then
        rejected("the shader file " .. path .. " does not exist")
    end
end
