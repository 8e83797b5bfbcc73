-- grayscale: linear ramp, black and transparent at the bottom of the window to white and
-- opaque at its top.
-- A preset is normalised (ParaView's convention): each point is {fraction of the data's value
-- window, r, g, b, alpha per unit length}, so it follows the data it is applied to: the window
-- of an 8-bit volume is 0..255 (fraction c/255 is code c), of a 16-bit or float series its
-- range over all timesteps, of a store its quantisation window. cdvr.tf("grayscale", {range={lo, hi}})
-- pins it to data values instead.
return {
  normalized = true,
  {0, 0, 0, 0, 0},
  {1, 1, 1, 1, 1},
}
