// Golden values from basalt's camera headers (github:VladyslavUsenko/basalt-headers, include/basalt/camera/).
// Built and run by scripts/golden_cameras.py; reads from stdin:
//   <model: ds|eucm|kb4|unified> <n params> <params...>
//   <n points> then n lines "x y z"   (projected)
//   <n pixels> then n lines "u v"     (unprojected)
// and prints, one line each, "valid u v" for the points and "valid x y z" for the pixels (%.17g).
#include <cstdio>
#include <iostream>
#include <vector>

#include <basalt/camera/double_sphere_camera.hpp>
#include <basalt/camera/extended_camera.hpp>
#include <basalt/camera/kannala_brandt_camera4.hpp>
#include <basalt/camera/unified_camera.hpp>

template <class Cam>
void run(const Cam& cam) {
  int n;
  std::cin >> n;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector4d p(0, 0, 0, 0);
    std::cin >> p[0] >> p[1] >> p[2];
    Eigen::Vector2d uv;
    bool ok = cam.project(p, uv);
    std::printf("%d %.17g %.17g\n", ok ? 1 : 0, uv[0], uv[1]);
  }
  std::cin >> n;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector2d uv;
    std::cin >> uv[0] >> uv[1];
    Eigen::Vector4d r;
    bool ok = cam.unproject(uv, r);
    std::printf("%d %.17g %.17g %.17g\n", ok ? 1 : 0, r[0], r[1], r[2]);
  }
}

template <int N, class Cam>
void run_with(const std::vector<double>& prm) {
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = prm[i];
  run(Cam(v));
}

int main() {
  std::string model;
  int np;
  std::cin >> model >> np;
  std::vector<double> prm(np);
  for (auto& x : prm) std::cin >> x;
  if (model == "ds") run_with<6, basalt::DoubleSphereCamera<double>>(prm);
  else if (model == "eucm") run_with<6, basalt::ExtendedUnifiedCamera<double>>(prm);
  else if (model == "kb4") run_with<8, basalt::KannalaBrandtCamera4<double>>(prm);
  else if (model == "unified") run_with<5, basalt::UnifiedCamera<double>>(prm);
  else return 2;
  return 0;
}
