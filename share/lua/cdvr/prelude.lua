-- cdvr.prelude: the parts of the cdvr API written in Lua. The host requires this module
-- after the C functions are registered; each piece lives in its own module under
-- share/lua/cdvr/ and is attached to the cdvr table here.
local cdvr = require "cdvr"

local path = require "cdvr.path"
local policy = require "cdvr.policy"
local schedule = require "cdvr.schedule"
local serialize = require "cdvr.serialize"

cdvr.path = path
cdvr.policy = policy
cdvr.schedule = schedule
cdvr.save_lua = serialize.save_lua
cdvr.load_lua = serialize.load_lua

local HELP = {
  { "cdvr.save_lua(value, file)", "write a value as a plain Lua file `return {...}` (objects via :totable())" },
  { "cdvr.load_lua(file)", "load a plain Lua data file (text, empty environment, no calls, budgeted) -> value or nil, message; code: dofile" },
  { "cdvr.path.orbit{center=, distance=, period=, ...}", "camera path turning around center (up, elevation, start, fov)" },
  { "cdvr.path.keyframes{ {time=, eye=, center=}, ... }", "camera path through keys, Catmull-Rom (loop, spline, period)" },
  { "cdvr.path.fn(function(t) ... end)", "camera path from a Lua function returning {eye=, center=, up=, fov=}" },
  { "cdvr.path.from(tbl)", "rebuild a camera path from its p:totable() table" },
  { "cdvr.path.save(p, file)", "save a camera path to a plain Lua file" },
  { "cdvr.path.load(file)", "load a camera path saved by cdvr.path.save -> path (raises naming the file)" },
  { "p(t)", "camera path at time t -> {eye=, center=, up=, fov=}" },
  { "p:camera(t, width, height [, opts])", "camera path at time t as a cdvr.camera" },
  { "p:totable()", "camera path as a plain table" },
  { "cdvr.policy.fixed([variant])", "rate control: always the same variant (default the best quality)" },
  { "cdvr.policy.open_loop{target_fps=, margin=0.9}", "rate control: best quality whose predicted frame time fits" },
  { "cdvr.policy.closed_loop{target_fps=, hysteresis=0.1}", "rate control: step variants on the measured frame time" },
  { "cdvr.policy.get(name_or_fn [, opts])", "policy from 'fixed', 'open_loop', 'closed_loop' or a function" },
  { "cdvr.policy.measure(frames [, variants])", "bandwidths and fixed stage times measured on stats.frames (for custom policies); with stats.variants, unzip rates per stage 2" },
  { "cdvr.policy.predict(variant, m [, pipelined])", "predicted frame time (ms) of a variant from cdvr.policy.measure" },
  { "policy(stats) -> variant [, reason]", "rate-control contract; stats fields documented in share/lua/cdvr/policy.lua" },
  { "cdvr.path.is_path(x)", "true when x is a camera path" },
  { "cdvr.schedule.quantile(values, q)", "quantile q in [0, 1] of a list (linear between order statistics)" },
  { "cdvr.schedule.fixed{S=, T=}", "encode schedule: the same parameters for every group" },
  { "cdvr.schedule.change_driven(v, {fast=, slow=, quantile=})", "encode schedule: better quality where the series changes fastest" },
  { "cdvr.schedule.from_changes(changes, opts)", "encode schedule from given per-timestep change values" },
}
for _, entry in ipairs(HELP) do
  cdvr.help_add(entry[1], entry[2])
end

-- true, not the cdvr table: tracebacks then name functions "cdvr.render", not
-- "cdvr.prelude.render" (Lua names a function after the first loaded module holding it).
return true
