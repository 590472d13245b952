#pragma once
/// @file Eigen aliases shared by the engine. Units are SI throughout (PHYSICS.md section 1).

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <vector>

namespace fiberfem::core {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Mat6x12 = Eigen::Matrix<double, 6, 12>;
/// Node positions, one column per node (3 x N), metres.
using Positions = Eigen::Matrix3Xd;
/// One tetrahedron: four node indices.
using Tet = std::array<int, 4>;
/// One boundary triangle: three node indices, counter-clockwise seen from outside.
using Tri = std::array<int, 3>;

}  // namespace fiberfem::core
