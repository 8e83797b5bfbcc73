-- ct_bone: dense material (metal, bone) opaque and bright; mid densities faint, air invisible.
-- Tuned on the engine CT (block material 128-160, dense inserts above 180 of 0-255).
-- A preset is normalised (ParaView's convention): each point is {fraction of the data's value
-- window, r, g, b, alpha per unit length}, so it follows the data it is applied to: the window
-- of an 8-bit volume is 0..255 (fraction c/255 is code c), of a 16-bit or float series its
-- range over all timesteps, of a store its quantisation window. cdvr.tf("ct_bone", {range={lo, hi}})
-- pins it to data values instead.
return {
  normalized = true,
  {0, 0, 0, 0, 0},
  {120 / 255, 0.5, 0.3, 0.2, 0},
  {140 / 255, 0.8, 0.6, 0.5, 0.02},
  {165 / 255, 0.9, 0.8, 0.7, 0.03},
  {185 / 255, 1, 0.95, 0.85, 0.6},
  {1, 1, 1, 1, 0.95},
}
