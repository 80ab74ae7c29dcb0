// Camera maths without GL: glTF and orbit cameras to CameraView, and the projection.
#include "camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace prt::render {

// Reversed depth (near → 1, far → 0) with glClipControl(GL_ZERO_TO_ONE) and a float depth
// buffer: float precision then falls where depth values are small, which makes the precision
// nearly uniform in distance and allows an infinite far plane.
glm::dmat4 projection(const CameraView& c, double aspect, double orthoFar) {
  glm::dmat4 p(0.0);
  const double n = c.znear;
  if (c.perspective) {
    const double f = 1.0 / std::tan(0.5 * c.yfov);
    p[0][0] = f / aspect;
    p[1][1] = f;
    p[2][3] = -1.0;  // w_clip = -z_view
    if (c.zfar > 0.0) {
      // depth = (A z + B) / -z with depth(-n) = 1, depth(-far) = 0.
      p[2][2] = n / (c.zfar - n);
      p[3][2] = n * c.zfar / (c.zfar - n);
    } else {
      p[3][2] = n;  // depth = n / -z
    }
  } else {
    const double far = c.zfar > 0.0 ? c.zfar : orthoFar;
    p[0][0] = 1.0 / (c.ymag * aspect);
    p[1][1] = 1.0 / c.ymag;
    p[2][2] = 1.0 / (far - n);  // depth = (z + far) / (far - n): 1 at -n, 0 at -far
    p[3][2] = far / (far - n);
    p[3][3] = 1.0;
  }
  return p;
}

CameraView cameraView(const Camera& camera) {
  CameraView v;
  v.cameraToWorld = camera.world;
  for (int i = 0; i < 3; ++i) {
    const glm::dvec3 axis(camera.world[i]);
    const double len = glm::length(axis);
    if (len > 0.0) v.cameraToWorld[i] = glm::dvec4(axis / len, 0.0);
  }
  v.perspective = camera.perspective;
  v.yfov = camera.yfov;
  v.ymag = camera.ymag;
  v.znear = camera.znear;
  v.zfar = camera.zfar;
  return v;
}

void orbitFraming(const Scene& scene, glm::dvec3& lo, glm::dvec3& hi) {
  lo = glm::dvec3(scene.boundsMin);
  hi = glm::dvec3(scene.boundsMax);
  size_t n = 0;
  for (const MeshInstance& m : scene.meshes) n += m.vertexCount();
  if (n < 100) return;  // too few for percentiles to mean anything
  // At most ~64k positions, taken evenly: percentiles need no more.
  const size_t stride = std::max<size_t>(1, n / 65536);
  std::array<std::vector<float>, 3> axis;
  size_t i = 0;
  for (const MeshInstance& m : scene.meshes)
    for (const glm::vec3& p : m.positions)
      if (i++ % stride == 0)
        for (int a = 0; a < 3; ++a) axis[size_t(a)].push_back(p[a]);
  glm::dvec3 tlo, thi;
  for (int a = 0; a < 3; ++a) {
    std::vector<float>& v = axis[size_t(a)];
    const size_t k0 = v.size() / 100, k1 = v.size() - 1 - v.size() / 100;
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(k0), v.end());
    tlo[a] = v[k0];
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(k1), v.end());
    thi[a] = v[k1];
  }
  if (glm::length(thi - tlo) < 0.5 * glm::length(hi - lo)) {
    lo = tlo;
    hi = thi;
  }
}

glm::dvec3 orbitTarget(const Scene& scene, const OrbitCamera& orbit) {
  if (orbit.target) return glm::dvec3(*orbit.target);
  glm::dvec3 lo, hi;
  orbitFraming(scene, lo, hi);
  return 0.5 * (lo + hi);
}

CameraView orbitView(const Scene& scene, const OrbitCamera& orbit, double aspect) {
  glm::dvec3 lo, hi;
  orbitFraming(scene, lo, hi);
  const glm::dvec3 target = orbitTarget(scene, orbit);
  double radius = 0.5 * glm::length(hi - lo);
  if (!(radius > 0.0)) radius = 1.0;
  CameraView v;
  v.yfov = glm::radians(orbit.yfovDegrees);
  double distance = orbit.distance;
  if (distance <= 0.0) {
    // The bounding sphere touches the narrower of the two fields of view.
    const double half = std::min(0.5 * v.yfov, std::atan(std::tan(0.5 * v.yfov) * aspect));
    distance = radius / std::sin(half);
  }
  const double az = glm::radians(orbit.azimuthDegrees);
  const double el = glm::radians(std::clamp(orbit.elevationDegrees, -89.0, 89.0));
  const glm::dvec3 back(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  const glm::dvec3 right = glm::normalize(glm::cross(glm::dvec3(0, 1, 0), back));
  const glm::dvec3 up = glm::cross(back, right);
  v.cameraToWorld =
      glm::dmat4(glm::dvec4(right, 0), glm::dvec4(up, 0), glm::dvec4(back, 0), glm::dvec4(target + distance * back, 1));
  v.znear = std::max(0.5 * (distance - radius), 1e-3 * radius);
  v.zfar = 0.0;
  return v;
}

}  // namespace prt::render
