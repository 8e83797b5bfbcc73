-- hot: black - red - yellow - white colour map with opacity rising with the value
-- (simulation fields, densities).
return {
  {0, 0, 0, 0, 0},
  {85, 1, 0, 0, 0.1},
  {170, 1, 1, 0, 0.4},
  {255, 1, 1, 1, 0.8},
}
