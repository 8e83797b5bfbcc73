-- mri: T1 MRI, background and CSF invisible, grey and white matter in soft greys, bright
-- structures (fat, vessels) more opaque.
-- A preset is normalised (ParaView's convention): each point is {fraction of the data's value
-- window, r, g, b, alpha per unit length}, so it follows the data it is applied to: the window
-- of an 8-bit volume is 0..255 (fraction c/255 is code c), of a 16-bit or float series its
-- range over all timesteps, of a store its quantisation window. cdvr.tf("mri", {range={lo, hi}})
-- pins it to data values instead.
return {
  normalized = true,
  {0, 0, 0, 0, 0},
  {20 / 255, 0, 0, 0, 0},
  {60 / 255, 0.6, 0.5, 0.45, 0.02},
  {100 / 255, 0.9, 0.8, 0.75, 0.08},
  {180 / 255, 1, 1, 0.95, 0.3},
  {1, 1, 1, 1, 0.5},
}
