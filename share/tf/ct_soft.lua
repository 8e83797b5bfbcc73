-- ct_soft: lower densities (soft tissue, light material) in warm semi-transparent colours,
-- dense material whiter and more opaque.
return {
  {0, 0, 0, 0, 0},
  {30, 0.6, 0.2, 0.1, 0},
  {70, 0.9, 0.5, 0.4, 0.03},
  {120, 1, 0.8, 0.7, 0.08},
  {170, 1, 0.95, 0.9, 0.25},
  {255, 1, 1, 1, 0.5},
}
