-- ct_soft: lower densities (soft tissue, light material) in warm semi-transparent colours,
-- dense material whiter and more opaque.
-- A preset is normalised (ParaView's convention): each point is {fraction of the data's value
-- window, r, g, b, alpha per unit length}, so it follows the data it is applied to: the window
-- of an 8-bit volume is 0..255 (fraction c/255 is code c), of a 16-bit or float series its
-- range over all timesteps, of a store its quantisation window. cdvr.tf("ct_soft", {range={lo, hi}})
-- pins it to data values instead.
return {
  normalized = true,
  {0, 0, 0, 0, 0},
  {30 / 255, 0.6, 0.2, 0.1, 0},
  {70 / 255, 0.9, 0.5, 0.4, 0.03},
  {120 / 255, 1, 0.8, 0.7, 0.08},
  {170 / 255, 1, 0.95, 0.9, 0.25},
  {1, 1, 1, 1, 0.5},
}
