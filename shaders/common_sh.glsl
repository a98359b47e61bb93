// SH basis and helpers shared by the compute shaders: the convention of core/sh/sh.h
// (real orthonormal SH, no Condon-Shortley phase, index l*l + l + m) and the link encodings
// of core/links/links.h (fp16 coefficients packed two per uint, octahedral snorm16 pairs).
// Expects BANDS (output bands, 1..4) to be defined; NC = BANDS * BANDS.
#define NC (BANDS * BANDS)

const float kY00 = 0.282094791773878;
const float kY1 = 0.488602511902920;
const float kY2Cross = 1.092548430592079;
const float kY20 = 0.315391565252520;
const float kY22 = 0.546274215296040;
const float kY33 = 0.590043589926644;
const float kY3Xyz = 2.890611442640554;
const float kY31 = 0.457045799464466;
const float kY30 = 0.373176332590115;
const float kY32 = 1.445305721320277;
const float kPi = 3.14159265358979;

int bandOf(int i) { return i < 1 ? 0 : i < 4 ? 1 : i < 9 ? 2 : 3; }

// Y_i(d) for i < NC, d unit length.
void evalBasis(vec3 d, out float y[NC]) {
  y[0] = kY00;
#if BANDS >= 2
  y[1] = kY1 * d.y;
  y[2] = kY1 * d.z;
  y[3] = kY1 * d.x;
#endif
#if BANDS >= 3
  float xx = d.x * d.x, yy = d.y * d.y, zz = d.z * d.z;
  y[4] = kY2Cross * d.x * d.y;
  y[5] = kY2Cross * d.y * d.z;
  y[6] = kY20 * (3.0 * zz - 1.0);
  y[7] = kY2Cross * d.x * d.z;
  y[8] = kY22 * (xx - yy);
#endif
#if BANDS >= 4
  y[9] = kY33 * d.y * (3.0 * xx - yy);
  y[10] = kY3Xyz * d.x * d.y * d.z;
  y[11] = kY31 * d.y * (5.0 * zz - 1.0);
  y[12] = kY30 * d.z * (5.0 * zz - 3.0);
  y[13] = kY31 * d.x * (5.0 * zz - 1.0);
  y[14] = kY32 * d.z * (xx - yy);
  y[15] = kY33 * d.x * (xx - 3.0 * yy);
#endif
}

// Clamped-cosine zonal factor of band l (pi, 2pi/3, pi/4, 0).
float irradianceBandFactor(int l) { return l == 0 ? kPi : l == 1 ? 2.0 * kPi / 3.0 : l == 2 ? kPi / 4.0 : 0.0; }

// links::decodeOctahedral.
vec3 decodeOctahedral(uint bits) {
  float x = float(int(bits << 16) >> 16) / 32767.0;
  float y = float(int(bits) >> 16) / 32767.0;
  vec3 v = vec3(x, y, 1.0 - abs(x) - abs(y));
  if (v.z < 0.0) {
    v.x = (1.0 - abs(y)) * (x >= 0.0 ? 1.0 : -1.0);
    v.y = (1.0 - abs(x)) * (y >= 0.0 ? 1.0 : -1.0);
  }
  return normalize(v);
}

// relight::capBandFactors: spherical-cap band factors from omega / pi.
void capBandFactors(float omega_over_pi, out float k[4]) {
  float c = clamp(1.0 - 0.5 * omega_over_pi, -1.0, 1.0);
  float s = 1.0 - c * c;
  k[0] = 2.0 * (1.0 - c);
  k[1] = s;
  k[2] = c * s;
  k[3] = -0.25 * s * (1.0 - 5.0 * c * c);
}
