-- grayscale: linear ramp, black and transparent at 0 to white and opaque at 255.
-- Each point: {value (raw 8-bit), r, g, b, alpha per unit length}.
return {
  {0, 0, 0, 0, 0},
  {255, 1, 1, 1, 1},
}
