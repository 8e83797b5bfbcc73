-- ct_bone: dense material (metal, bone) opaque and bright; mid densities faint, air invisible.
-- Tuned on the engine CT (block material 128-160, dense inserts above 180).
return {
  {0, 0, 0, 0, 0},
  {120, 0.5, 0.3, 0.2, 0},
  {140, 0.8, 0.6, 0.5, 0.02},
  {165, 0.9, 0.8, 0.7, 0.03},
  {185, 1, 0.95, 0.85, 0.6},
  {255, 1, 1, 1, 0.95},
}
