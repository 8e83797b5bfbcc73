-- mri: T1 MRI, background and CSF invisible, grey and white matter in soft greys, bright
-- structures (fat, vessels) more opaque.
return {
  {0, 0, 0, 0, 0},
  {20, 0, 0, 0, 0},
  {60, 0.6, 0.5, 0.45, 0.02},
  {100, 0.9, 0.8, 0.75, 0.08},
  {180, 1, 1, 0.95, 0.3},
  {255, 1, 1, 1, 0.5},
}
