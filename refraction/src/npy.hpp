#pragma once
// The .npy writer moved to geometry (clearfit/npy.hpp) so every module can export arrays.
#include <clearfit/npy.hpp>
