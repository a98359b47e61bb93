// Tests for core/rt: analytic hits and misses, batched == single, multithreaded == serial,
// and ray offsets that hold at millimetre and kilometre scene scales.
#include "core/rt/accel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace lightlink::rt {
namespace {

using glm::vec3;

// A planar quad corner, corner+e0, corner+e0+e1, corner+e1 as triangles (0,1,2), (0,2,3):
// front face (counter-clockwise) along cross(e0, e1).
scene::MeshInstance makeQuad(const std::string& name, vec3 corner, vec3 e0, vec3 e1) {
  scene::MeshInstance mesh;
  mesh.name = name;
  mesh.positions = {corner, corner + e0, corner + e0 + e1, corner + e1};
  const vec3 n = glm::normalize(glm::cross(e0, e1));
  mesh.normals.assign(4, n);
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

// Six quads (one mesh per face, so a hit names its face) of the box [lo, hi], front faces
// pointing inwards. Face order: -x, +x, -y, +y, -z, +z walls.
std::vector<scene::MeshInstance> makeBoxFaces(vec3 lo, vec3 hi) {
  const vec3 d = hi - lo;
  const vec3 ex(d.x, 0, 0), ey(0, d.y, 0), ez(0, 0, d.z);
  return {
      makeQuad("-x", lo, ey, ez),                      // normal +x
      makeQuad("+x", vec3(hi.x, lo.y, lo.z), ez, ey),  // normal -x
      makeQuad("-y", lo, ez, ex),                      // normal +y
      makeQuad("+y", vec3(lo.x, hi.y, lo.z), ex, ez),  // normal -y
      makeQuad("-z", lo, ex, ey),                      // normal +z
      makeQuad("+z", vec3(lo.x, lo.y, hi.z), ey, ex),  // normal -z
  };
}

scene::Scene sceneOf(std::vector<scene::MeshInstance> meshes) {
  scene::Scene s;
  s.meshes = std::move(meshes);
  return s;
}

Accel buildOrDie(const scene::Scene& s, const AccelOptions& options = {}) {
  Expected<Accel> accel = Accel::build(s, options);
  EXPECT_TRUE(accel.hasValue()) << accel.status().toString();
  if (!accel.hasValue()) std::abort();
  return std::move(accel).value();
}

vec3 uniformSphere(std::mt19937& rng) {
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  const float z = 1.0f - 2.0f * u01(rng);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = 6.2831853f * u01(rng);
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Cosine-distributed direction about unit n.
vec3 cosineAbout(const vec3& n, std::mt19937& rng) {
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  const float r = std::sqrt(u01(rng));
  const float phi = 6.2831853f * u01(rng);
  const vec3 t =
      glm::normalize(std::abs(n.x) > 0.5f ? glm::cross(n, vec3(0, 1, 0)) : glm::cross(n, vec3(1, 0, 0)));
  const vec3 b = glm::cross(n, t);
  return r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0f, 1.0f - r * r)) * n;
}

// ---- single rays against a unit quad ---------------------------------------------------

class UnitQuad : public ::testing::Test {
 protected:
  // z = 0, [0,1]^2, front face +z: v0=(0,0,0) v1=(1,0,0) v2=(1,1,0) v3=(0,1,0).
  UnitQuad() : accel_(buildOrDie(sceneOf({makeQuad("quad", vec3(0), vec3(1, 0, 0), vec3(0, 1, 0))}))) {}
  Accel accel_;
};

TEST_F(UnitQuad, HitReportsDistanceBarycentricsIdsAndNormal) {
  // (0.75, 0.25) lies in triangle 0 (v0 v1 v2): p = v0 + u(v1-v0) + v(v2-v0) = (u+v, v).
  const Hit h = accel_.intersect(Ray{vec3(0.75f, 0.25f, 2.0f), 0.0f, vec3(0, 0, -1)});
  ASSERT_TRUE(h.hit());
  EXPECT_EQ(h.mesh, 0u);
  EXPECT_EQ(h.triangle, 0u);
  EXPECT_NEAR(h.t, 2.0f, 1e-6f);
  EXPECT_NEAR(h.u, 0.5f, 1e-6f);
  EXPECT_NEAR(h.v, 0.25f, 1e-6f);
  // ng = cross(v1 - v0, v2 - v0) = (0, 0, 1) for this triangle (unit area x2 = 1).
  EXPECT_NEAR(h.ng.x, 0.0f, 1e-6f);
  EXPECT_NEAR(h.ng.y, 0.0f, 1e-6f);
  EXPECT_NEAR(h.ng.z, 1.0f, 1e-6f);
  EXPECT_FALSE(h.backFacing(vec3(0, 0, -1)));

  // (0.25, 0.75) lies in triangle 1 (v0 v2 v3): p = u(1,1,0) + v(0,1,0).
  const Hit h1 = accel_.intersect(Ray{vec3(0.25f, 0.75f, 2.0f), 0.0f, vec3(0, 0, -1)});
  ASSERT_TRUE(h1.hit());
  EXPECT_EQ(h1.triangle, 1u);
  EXPECT_NEAR(h1.u, 0.25f, 1e-6f);
  EXPECT_NEAR(h1.v, 0.5f, 1e-6f);
  EXPECT_GT(h1.ng.z, 0.0f);
}

TEST_F(UnitQuad, DistanceIsInUnitsOfDirLength) {
  const Hit h = accel_.intersect(Ray{vec3(0.5f, 0.2f, 3.0f), 0.0f, vec3(0, 0, -4)});
  ASSERT_TRUE(h.hit());
  EXPECT_NEAR(h.t, 0.75f, 1e-6f);
}

TEST_F(UnitQuad, BackFaceHitsAreReportedAsSuch) {
  const Ray up{vec3(0.3f, 0.6f, -1.5f), 0.0f, vec3(0, 0, 1)};
  const Hit h = accel_.intersect(up);
  ASSERT_TRUE(h.hit());
  EXPECT_NEAR(h.t, 1.5f, 1e-6f);
  EXPECT_TRUE(h.backFacing(up.dir));
  EXPECT_TRUE(accel_.occluded(up));
}

TEST_F(UnitQuad, MissesParallelOutsideAndOutOfRange) {
  // Parallel to the quad, just above it.
  const Ray parallel{vec3(-1.0f, 0.5f, 0.01f), 0.0f, vec3(1, 0, 0)};
  EXPECT_FALSE(accel_.intersect(parallel).hit());
  EXPECT_FALSE(accel_.occluded(parallel));
  // Beside the quad.
  const Ray beside{vec3(1.5f, 0.5f, 1.0f), 0.0f, vec3(0, 0, -1)};
  EXPECT_FALSE(accel_.intersect(beside).hit());
  EXPECT_FALSE(accel_.occluded(beside));
  // The quad is at t = 2: tfar just short of it misses, just past it hits.
  Ray down{vec3(0.5f, 0.5f, 2.0f), 0.0f, vec3(0, 0, -1), 1.99f};
  EXPECT_FALSE(accel_.intersect(down).hit());
  EXPECT_FALSE(accel_.occluded(down));
  down.tfar = 2.01f;
  EXPECT_TRUE(accel_.intersect(down).hit());
  EXPECT_TRUE(accel_.occluded(down));
  // tnear past the quad misses too.
  down.tnear = 2.01f;
  down.tfar = 10.0f;
  EXPECT_FALSE(accel_.intersect(down).hit());
  EXPECT_FALSE(accel_.occluded(down));
  // Pointing away.
  EXPECT_FALSE(accel_.intersect(Ray{vec3(0.5f, 0.5f, 2.0f), 0.0f, vec3(0, 0, 1)}).hit());
}

TEST_F(UnitQuad, ReportsScaleAndTriangleCount) {
  EXPECT_EQ(accel_.triangleCount(), 2u);
  EXPECT_NEAR(accel_.sceneScale(), std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(accel_.rayEpsilon(), 1e-5f * std::sqrt(2.0f), 1e-9f);
  EXPECT_TRUE(accel_.deviceStatus().isOk());
}

TEST_F(UnitQuad, MovedAccelStillTraces) {
  Accel moved = std::move(accel_);
  EXPECT_TRUE(moved.intersect(Ray{vec3(0.5f, 0.5f, 1.0f), 0.0f, vec3(0, 0, -1)}).hit());
}

// ---- closed box from the inside ----------------------------------------------------------

// Analytic distance from c (inside the box) along d to the box boundary.
float distanceToBoxWall(vec3 lo, vec3 hi, vec3 c, vec3 d) {
  float t = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0.0f) t = std::min(t, (hi[a] - c[a]) / d[a]);
    if (d[a] < 0.0f) t = std::min(t, (lo[a] - c[a]) / d[a]);
  }
  return t;
}

TEST(AccelBox, EveryDirectionFromInsideHitsAtAnalyticDistance) {
  const vec3 lo(-1.0f, -2.0f, -0.5f), hi(3.0f, 1.0f, 2.5f);
  const Accel accel = buildOrDie(sceneOf(makeBoxFaces(lo, hi)));
  std::mt19937 rng(7);
  std::vector<vec3> dirs;
  for (int i = 0; i < 20000; ++i) dirs.push_back(uniformSphere(rng));
  const vec3 c(0.25f, -0.5f, 1.0f);
  // Directions through the 8 corners and 12 edge midpoints: the watertightness cases
  // (a ray through a shared edge or vertex must hit one of its triangles).
  for (int i = 0; i < 8; ++i)
    dirs.push_back(vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z) - c);
  const vec3 mid = 0.5f * (lo + hi);
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i < 4; ++i) {
      vec3 p = mid;
      const int b = (a + 1) % 3, e = (a + 2) % 3;
      p[b] = i & 1 ? hi[b] : lo[b];
      p[e] = i & 2 ? hi[e] : lo[e];
      dirs.push_back(p - c);
    }
  // Diagonals of each face quad (the edge shared by its two triangles).
  dirs.push_back(vec3(hi.x, 0.3f * lo.y + 0.7f * hi.y, 0.3f * lo.z + 0.7f * hi.z) - c);
  std::size_t misses = 0;
  for (const vec3& d : dirs) {
    const Hit h = accel.intersect(Ray{c, 0.0f, d});
    if (!h.hit()) {
      ++misses;
      continue;
    }
    const float expected = distanceToBoxWall(lo, hi, c, d);
    EXPECT_NEAR(h.t, expected, 1e-5f * expected) << "dir " << d.x << " " << d.y << " " << d.z;
    // Faces point inwards, so from inside every hit is a front-face hit.
    EXPECT_FALSE(h.backFacing(d));
  }
  EXPECT_EQ(misses, 0u) << "rays leaked out of a closed box";
}

// ---- batches, threads --------------------------------------------------------------------

scene::Scene mixedScene() {
  std::vector<scene::MeshInstance> meshes = makeBoxFaces(vec3(-4, -4, -4), vec3(4, 4, 4));
  // Some clutter inside so hits vary in mesh, triangle and distance.
  for (int i = 0; i < 10; ++i) {
    const float s = 0.7f * static_cast<float>(i) - 3.0f;
    meshes.push_back(makeQuad("slab" + std::to_string(i), vec3(s, -2.0f + 0.2f * i, -1.0f),
                              vec3(1.2f, 0.1f, 0.3f), vec3(0.2f, 0.4f, 1.5f)));
  }
  return sceneOf(std::move(meshes));
}

std::vector<Ray> randomRays(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-3.9f, 3.9f), len(0.1f, 3.0f), far(0.5f, 12.0f);
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    r.origin = vec3(pos(rng), pos(rng), pos(rng));
    r.dir = uniformSphere(rng) * len(rng);  // non-unit on purpose
    r.tnear = 0.0f;
    r.tfar = rng() % 4 == 0 ? far(rng) : std::numeric_limits<float>::infinity();
  }
  return rays;
}

void expectSameHit(const Hit& a, const Hit& b, std::size_t i) {
  ASSERT_EQ(a.mesh, b.mesh) << "ray " << i;
  if (!a.hit()) return;
  EXPECT_EQ(a.triangle, b.triangle) << "ray " << i;
  EXPECT_NEAR(a.t, b.t, 1e-5f * a.t) << "ray " << i;
  EXPECT_NEAR(a.u, b.u, 1e-5f) << "ray " << i;
  EXPECT_NEAR(a.v, b.v, 1e-5f) << "ray " << i;
  EXPECT_NEAR(glm::length(a.ng - b.ng), 0.0f, 1e-5f * glm::length(a.ng)) << "ray " << i;
}

TEST(AccelBatch, BatchedEqualsSingleForEveryCountAndCoherence) {
  const Accel accel = buildOrDie(mixedScene());
  const std::vector<Ray> all = randomRays(1000, 11);
  std::size_t hits_seen = 0, blocked_seen = 0;
  for (std::size_t count : {std::size_t{1000}, std::size_t{999}, std::size_t{33}, std::size_t{16},
                            std::size_t{15}, std::size_t{1}, std::size_t{0}}) {
    const std::span<const Ray> rays(all.data(), count);
    for (Coherence coherence : {Coherence::kIncoherent, Coherence::kCoherent}) {
      std::vector<Hit> hits(count);
      std::vector<std::uint8_t> blocked(count, 7);
      accel.intersect(rays, hits, coherence);
      accel.occluded(rays, blocked, coherence);
      for (std::size_t i = 0; i < count; ++i) {
        expectSameHit(hits[i], accel.intersect(rays[i]), i);
        EXPECT_EQ(blocked[i], accel.occluded(rays[i]) ? 1 : 0) << "ray " << i;
        EXPECT_EQ(blocked[i] == 1, hits[i].hit()) << "ray " << i;
        hits_seen += hits[i].hit();
        blocked_seen += blocked[i];
      }
    }
  }
  // The ray set must exercise both outcomes, or the comparison proves little.
  EXPECT_GT(hits_seen, 0u);
  EXPECT_LT(blocked_seen, 2u * (1000 + 999 + 33 + 16 + 15 + 1));
}

// A fan (one origin, direction arrays) gives the hits of the same rays as rt::Ray records
// through the coherent batch call, bit for bit (the same packets), for fan sizes that do and
// do not fill the last packet; a miss reads mesh = kNoHit, t = tfar and zeros.
// mixedScene behind a mesh without triangles: geometry g then holds mesh g + 1.
scene::Scene mixedSceneWithEmptyMesh() {
  scene::Scene s = mixedScene();
  scene::MeshInstance empty;
  empty.name = "empty";
  s.meshes.insert(s.meshes.begin(), empty);
  return s;
}

TEST(AccelBatch, FanEqualsTheCoherentBatchBitForBit) {
 for (const bool shifted : {false, true}) {
  SCOPED_TRACE(shifted ? "geometry g holds mesh g + 1" : "geometry g holds mesh g");
  const Accel accel = buildOrDie(shifted ? mixedSceneWithEmptyMesh() : mixedScene());
  std::mt19937 rng(5);
  std::size_t hits_seen = 0, misses_seen = 0, first_mesh_hits = 0;
  for (std::size_t count : {std::size_t{1024}, std::size_t{1000}, std::size_t{17}, std::size_t{16},
                            std::size_t{1}, std::size_t{0}}) {
    for (const vec3 origin : {vec3(0.1f, 0.2f, 0.3f), vec3(10.0f, 1.0f, -2.0f)}) {  // inside, outside the box
      std::vector<float> x(count), y(count), z(count);
      std::vector<Ray> rays(count);
      for (std::size_t i = 0; i < count; ++i) {
        const vec3 d = uniformSphere(rng);
        x[i] = d.x, y[i] = d.y, z[i] = d.z;
        rays[i] = Ray{origin, 0.0f, d, std::numeric_limits<float>::infinity()};
      }
      std::vector<Hit> expected(count);
      accel.intersect(rays, expected, Coherence::kCoherent);
      std::vector<std::uint32_t> mesh(count, 7), triangle(count, 7);
      std::vector<float> u(count, 7), v(count, 7), t(count, 7), nx(count, 7), ny(count, 7), nz(count, 7);
      RayFan fan;
      fan.origin = origin;
      fan.dir_x = x.data(), fan.dir_y = y.data(), fan.dir_z = z.data();
      fan.count = count;
      accel.intersectFan(fan, HitArrays{mesh.data(), triangle.data(), u.data(), v.data(), t.data(), nx.data(),
                                        ny.data(), nz.data()});
      for (std::size_t i = 0; i < count; ++i) {
        const Hit& h = expected[i];
        ASSERT_EQ(mesh[i], h.mesh) << "ray " << i;
        EXPECT_EQ(triangle[i], h.triangle) << "ray " << i;
        // Bit for bit: the same floats (a miss: t = inf as Hit's, the rest 0).
        EXPECT_EQ(u[i], h.u) << "ray " << i;
        EXPECT_EQ(v[i], h.v) << "ray " << i;
        EXPECT_EQ(t[i], h.t) << "ray " << i;
        EXPECT_EQ(nx[i], h.ng.x) << "ray " << i;
        EXPECT_EQ(ny[i], h.ng.y) << "ray " << i;
        EXPECT_EQ(nz[i], h.ng.z) << "ray " << i;
        hits_seen += h.hit() ? 1 : 0;
        misses_seen += h.hit() ? 0 : 1;
        first_mesh_hits += h.mesh == (shifted ? 1u : 0u) ? 1 : 0;
        if (shifted) {
          ASSERT_NE(h.mesh, 0u) << "ray " << i << " hit the mesh without triangles";
        }
      }
    }
  }
  EXPECT_GT(hits_seen, 100u);
  EXPECT_GT(misses_seen, 100u);
  EXPECT_GT(first_mesh_hits, 0u);
  EXPECT_TRUE(accel.deviceStatus().isOk());
 }
}

TEST(AccelBatch, ParallelBatchesEqualSerial) {
  const Accel accel = buildOrDie(mixedScene());
  const std::vector<Ray> rays = randomRays(100000, 23);
  for (Coherence coherence : {Coherence::kIncoherent, Coherence::kCoherent}) {
    std::vector<Hit> serial(rays.size()), parallel(rays.size());
    std::vector<std::uint8_t> serial_occ(rays.size()), parallel_occ(rays.size());
    accel.intersect(rays, serial, coherence);
    accel.occluded(rays, serial_occ, coherence);
    // Uneven grain (not a multiple of 16) so packet boundaries differ from the serial run.
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, rays.size(), 517),
        [&](const tbb::blocked_range<std::size_t>& r) {
          const std::span<const Ray> in(rays.data() + r.begin(), r.size());
          accel.intersect(in, std::span<Hit>(parallel.data() + r.begin(), r.size()), coherence);
          accel.occluded(in, std::span<std::uint8_t>(parallel_occ.data() + r.begin(), r.size()),
                         coherence);
        });
    for (std::size_t i = 0; i < rays.size(); ++i) {
      expectSameHit(serial[i], parallel[i], i);
      ASSERT_EQ(serial_occ[i], parallel_occ[i]) << "ray " << i;
    }
  }
  EXPECT_TRUE(accel.deviceStatus().isOk());
}

// ---- ray offsets at extreme scales -------------------------------------------------------

// A box of side `size` with its low corner at `corner`: rays leaving random points of each
// face must never hit that face again, and rays straight across must hit the opposite face
// at distance `size`.
void checkOffsetsInBox(float size, vec3 corner) {
  SCOPED_TRACE("box size " + std::to_string(size) + " at " + std::to_string(corner.x));
  const std::vector<scene::MeshInstance> faces = makeBoxFaces(corner, corner + vec3(size));
  const Accel accel = buildOrDie(sceneOf(faces));
  const vec3 extent = (corner + vec3(size)) - corner;  // as float stores it, far from the origin
  EXPECT_NEAR(accel.sceneScale(), glm::length(extent), 1e-6f * size);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::size_t self_hits = 0, leaks = 0, wrong_across = 0, bad_offsets = 0, rays = 0;
  // Float spacing relative to a coordinate's magnitude, and the largest coordinate here.
  constexpr float kUlp = 1.1920929e-7f;
  const vec3 far_corner = glm::max(glm::abs(corner), glm::abs(corner + vec3(size)));
  const float largest = std::max({far_corner.x, far_corner.y, far_corner.z});
  for (std::uint32_t f = 0; f < faces.size(); ++f) {
    const scene::MeshInstance& face = faces[f];
    const std::uint32_t opposite = f ^ 1u;
    const vec3 n_in = face.normals[0];
    for (int i = 0; i < 2000; ++i) {
      // A point on the face; a quarter of them within ~1e-4 of an edge or the diagonal,
      // where the neighbouring triangle is closest.
      float a = u01(rng), b = u01(rng);
      if (i % 4 == 1) a = 1e-4f * a;
      if (i % 4 == 2) b = std::clamp(a + 1e-4f * (b - 0.5f), 0.0f, 1.0f);
      const vec3 p = face.positions[0] + a * (face.positions[1] - face.positions[0]) +
                     b * (face.positions[3] - face.positions[0]);
      // Into the box: diffuse directions, including grazing ones.
      vec3 d = cosineAbout(n_in, rng);
      if (i % 8 == 3) d = glm::normalize(d - 0.9999f * glm::dot(d, n_in) * n_in);
      Hit h = accel.intersect(Ray{accel.offsetOrigin(p, n_in, d), 0.0f, d});
      ++rays;
      if (!h.hit())
        ++leaks;
      else if (h.mesh == f)
        ++self_hits;
      // Straight across: the opposite wall, at distance size minus the offset.
      const vec3 o = accel.offsetOrigin(p, n_in, n_in);
      const float offset = glm::dot(o - p, n_in);
      if (!(offset > 0.0f) || offset > 1e-4f * size + 32.0f * kUlp * largest) ++bad_offsets;
      h = accel.intersect(Ray{o, 0.0f, n_in});
      if (!h.hit() || h.mesh != opposite ||
          std::abs(h.t - (size - offset)) > 1e-5f * size + 8.0f * kUlp * largest)
        ++wrong_across;
      // Out of the box from the outside of the face: nothing to hit; the offset must put
      // the origin outside, not back inside.
      const vec3 out = -cosineAbout(n_in, rng);
      if (accel.intersect(Ray{accel.offsetOrigin(p, n_in, out), 0.0f, out}).hit()) ++self_hits;
    }
  }
  EXPECT_EQ(self_hits, 0u) << "of " << rays;
  EXPECT_EQ(leaks, 0u) << "of " << rays;
  EXPECT_EQ(wrong_across, 0u) << "of " << rays;
  EXPECT_EQ(bad_offsets, 0u) << "of " << rays;
}

TEST(AccelOffset, MillimetreScaleBox) { checkOffsetsInBox(1e-3f, vec3(-5e-4f)); }
TEST(AccelOffset, KilometreScaleBox) { checkOffsetsInBox(1e4f, vec3(-2e3f, 0.0f, -7e3f)); }
// A millimetre prop ten metres from the origin: float spacing of the coordinates (~1e-6),
// not the scene scale, limits precision there.
TEST(AccelOffset, MillimetreBoxFarFromOrigin) { checkOffsetsInBox(1e-3f, vec3(10.0f, -3.0f, 7.0f)); }

TEST(AccelOffset, OffsetIsSmallAndOnTheRaySide) {
  const Accel accel = buildOrDie(sceneOf({makeQuad("q", vec3(0), vec3(1e4f, 0, 0), vec3(0, 1e4f, 0))}));
  const vec3 p(5e3f, 5e3f, 0.0f), n(0, 0, 3.0f);  // unnormalised normal on purpose
  const vec3 up = accel.offsetOrigin(p, n, vec3(0.3f, 0.1f, 1.0f));
  const vec3 down = accel.offsetOrigin(p, n, vec3(0.3f, 0.1f, -1.0f));
  EXPECT_GT(up.z, 0.0f);
  EXPECT_LT(down.z, 0.0f);
  EXPECT_EQ(up.x, p.x);
  // rayEpsilon + 16 ulps of 5e3: ~0.14 m + ~0.01 m on a 14 km scene.
  const float expected = accel.rayEpsilon() + 16.0f * 1.1920929e-7f * 5e3f;
  EXPECT_NEAR(up.z, expected, 1e-3f * expected);
  EXPECT_NEAR(down.z, -expected, 1e-3f * expected);
}

// ---- static/dynamic and invalid input ----------------------------------------------------

TEST(AccelBuild, DynamicMeshesExcludedWhenStaticOnly) {
  // Mesh 0 is dynamic and in front; mesh 1 static behind it.
  scene::MeshInstance dynamic_quad = makeQuad("door", vec3(0, 0, 1), vec3(1, 0, 0), vec3(0, 1, 0));
  dynamic_quad.is_static = false;
  const scene::Scene s =
      sceneOf({dynamic_quad, makeQuad("wall", vec3(0), vec3(1, 0, 0), vec3(0, 1, 0))});
  const Ray down{vec3(0.5f, 0.5f, 2.0f), 0.0f, vec3(0, 0, -1)};

  const Accel statics = buildOrDie(s);
  EXPECT_EQ(statics.triangleCount(), 2u);
  Hit h = statics.intersect(down);
  ASSERT_TRUE(h.hit());
  EXPECT_EQ(h.mesh, 1u);  // the geometry id -> mesh index table skips the dynamic mesh
  EXPECT_NEAR(h.t, 2.0f, 1e-6f);

  AccelOptions all;
  all.static_only = false;
  all.quality = AccelOptions::Quality::kFast;
  const Accel everything = buildOrDie(s, all);
  EXPECT_EQ(everything.triangleCount(), 4u);
  h = everything.intersect(down);
  ASSERT_TRUE(h.hit());
  EXPECT_EQ(h.mesh, 0u);
  EXPECT_NEAR(h.t, 1.0f, 1e-6f);
}

TEST(AccelBuild, EmptyOrAllDynamicSceneIsInvalidInput) {
  Expected<Accel> empty = Accel::build(scene::Scene{});
  ASSERT_FALSE(empty.hasValue());
  EXPECT_EQ(empty.status().code(), Code::kInvalidInput);

  scene::MeshInstance dynamic_quad = makeQuad("door", vec3(0), vec3(1, 0, 0), vec3(0, 1, 0));
  dynamic_quad.is_static = false;
  Expected<Accel> only_dynamic = Accel::build(sceneOf({dynamic_quad}));
  ASSERT_FALSE(only_dynamic.hasValue());
  EXPECT_EQ(only_dynamic.status().code(), Code::kInvalidInput);

  scene::MeshInstance no_triangles;
  no_triangles.positions = {vec3(0), vec3(1)};
  Expected<Accel> nothing = Accel::build(sceneOf({no_triangles}));
  ASSERT_FALSE(nothing.hasValue());
  EXPECT_EQ(nothing.status().code(), Code::kInvalidInput);
}

TEST(AccelBuild, BadIndicesAndNonFinitePositionsAreInvalidInput) {
  scene::MeshInstance bad_index = makeQuad("bad index", vec3(0), vec3(1, 0, 0), vec3(0, 1, 0));
  bad_index.indices[4] = 4;
  Expected<Accel> a = Accel::build(sceneOf({bad_index}));
  ASSERT_FALSE(a.hasValue());
  EXPECT_EQ(a.status().code(), Code::kInvalidInput);
  EXPECT_NE(a.status().message().find("bad index"), std::string::npos) << a.status().message();

  scene::MeshInstance nan = makeQuad("nan", vec3(0), vec3(1, 0, 0), vec3(0, 1, 0));
  nan.positions[2].y = std::nanf("");
  Expected<Accel> b = Accel::build(sceneOf({nan}));
  ASSERT_FALSE(b.hasValue());
  EXPECT_EQ(b.status().code(), Code::kInvalidInput);
  EXPECT_NE(b.status().message().find("not finite"), std::string::npos) << b.status().message();
}

}  // namespace
}  // namespace lightlink::rt
