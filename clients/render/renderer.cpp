#include "clients/render/renderer.hpp"

#include "clients/render/colormap.hpp"
#include "clients/render/font.hpp"
#include "clients/render/osmesa_context.hpp"
#include "clients/render/overlay.hpp"
#include "clients/render/pv_loop.hpp"
#include "clients/render/surface.hpp"
#include "core/corotation.hpp"
#include "core/element.hpp"

#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace fiberfem::render {

void RenderSettings::validate() const {
  if (width < 16 || width > 8192) throw std::invalid_argument("width: " + std::to_string(width) + " px is outside [16, 8192]");
  if (height < 16 || height > 8192) throw std::invalid_argument("height: " + std::to_string(height) + " px is outside [16, 8192]");
  if (supersample < 1 || supersample > 4) throw std::invalid_argument("supersample: " + std::to_string(supersample) + " is outside [1, 4]");
  if (static_cast<long>(width) * supersample > 8192 || static_cast<long>(height) * supersample > 8192)
    throw std::invalid_argument("supersample: " + std::to_string(supersample) + " times the image size exceeds 8192 px per side");
  if (range && !(std::isfinite(range->first) && std::isfinite(range->second) && range->first < range->second))
    throw std::invalid_argument("range: needs finite min < max, got [" + std::to_string(range->first) + ", " +
                                std::to_string(range->second) + "]");
  if (!(fiber_length > 0 && fiber_length <= 10)) throw std::invalid_argument("fiber_length: must be in (0, 10]");
  if (max_fiber_glyphs < 1 || max_fiber_glyphs > 10000000) throw std::invalid_argument("max_fiber_glyphs: must be in [1, 1e7]");
  if (font_px != 0 && (font_px < 4 || font_px > 512)) throw std::invalid_argument("font_px: " + std::to_string(font_px) + " is outside [4, 512] (or 0: automatic)");
}

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Blinn-Phong per pixel with two directional lights fixed to the camera (a key light from
// the upper left front, a fill light from the right) and an ambient term; GLSL 1.20 on
// the compatibility profile (llvmpipe).
constexpr const char* kVertexShader = R"(#version 120
varying vec3 n_eye;
varying vec3 p_eye;
void main() {
  p_eye = (gl_ModelViewMatrix * gl_Vertex).xyz;
  n_eye = gl_NormalMatrix * gl_Normal;
  gl_FrontColor = gl_Color;
  gl_Position = ftransform();
}
)";
constexpr const char* kFragmentShader = R"(#version 120
varying vec3 n_eye;
varying vec3 p_eye;
uniform vec3 light_dir[2];
uniform float light_power[2];
uniform float ambient;
uniform float specular;
uniform float orthographic;
void main() {
  vec3 n = normalize(n_eye);
  if (!gl_FrontFacing) n = -n;
  vec3 v = orthographic > 0.5 ? vec3(0.0, 0.0, 1.0) : normalize(-p_eye);
  vec3 base = gl_Color.rgb;
  vec3 c = ambient * base;
  for (int i = 0; i < 2; ++i) {
    float d = max(dot(n, light_dir[i]), 0.0);
    vec3 h = normalize(light_dir[i] + v);
    float s = d > 0.0 ? pow(max(dot(n, h), 0.0), 40.0) : 0.0;
    c += light_power[i] * (d * base + specular * s);
  }
  gl_FragColor = vec4(min(c, vec3(1.0)), 1.0);
}
)";

GLuint compile(GLenum kind, const char* source) {
  const GLuint s = glCreateShader(kind);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("renderer: shader does not compile: ") + log);
  }
  return s;
}

}  // namespace

struct Renderer::Impl {
  const core::TetMesh& mesh;
  RenderSettings settings;
  Surface surface;
  OsmesaContext context;
  Camera camera;
  Font font;
  GLuint program = 0;
  double lo = 0, hi = 1;
  bool have_envelope = false;
  RenderTimes times;
  Image image;
  // Per-frame work arrays: one vertex per triangle corner.
  Eigen::Matrix3Xf vertices, normals;
  std::vector<std::uint8_t> colours;
  std::vector<double> element_values, node_values, node_weights;
  std::vector<float> glyphs;
  std::vector<std::uint8_t> glyph_colours;  // RGBA per glyph vertex

  Impl(const core::TetMesh& m, const RenderSettings& s)
      : mesh(m),
        settings(s),
        surface(m),
        context(s.width * s.supersample, s.height * s.supersample),
        font(s.font_px > 0 ? s.font_px : std::max(9, s.height / 42)) {
    camera = frame_points(CameraPreset::iso, surface_points(mesh), static_cast<double>(s.width) / s.height);
    program = glCreateProgram();
    glAttachShader(program, compile(GL_VERTEX_SHADER, kVertexShader));
    glAttachShader(program, compile(GL_FRAGMENT_SHADER, kFragmentShader));
    glLinkProgram(program);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (!ok) throw std::runtime_error("renderer: shader program does not link");
    if (s.field == Field::activation && !s.range) lo = 0, hi = 1;
    if (s.range) lo = s.range->first, hi = s.range->second;
  }

  void check(const FrameView& f) const {
    if (f.mesh.num_nodes() != mesh.num_nodes() || f.mesh.num_elements() != mesh.num_elements())
      throw std::invalid_argument("frame: mesh has " + std::to_string(f.mesh.num_nodes()) + " nodes and " +
                                  std::to_string(f.mesh.num_elements()) + " elements; the renderer's has " +
                                  std::to_string(mesh.num_nodes()) + " and " + std::to_string(mesh.num_elements()));
    if (f.x.rows() != 3 || f.x.cols() != mesh.num_nodes())
      throw std::invalid_argument("frame: positions are " + std::to_string(f.x.rows()) + " x " + std::to_string(f.x.cols()) +
                                  ", expected 3 x " + std::to_string(mesh.num_nodes()));
    if (!f.x.allFinite()) throw std::invalid_argument("frame: positions are not finite");
    const size_t ne = static_cast<size_t>(mesh.num_elements());
    if (settings.field == Field::activation && (!f.activation || f.activation->size() != ne))
      throw std::invalid_argument("field activation: the frame has no per-element activation (a scene without contraction? "
                                  "use --field displacement)");
    if ((settings.field == Field::fiber_strain || settings.fibers) && (!f.fibers || f.fibers->size() != ne))
      throw std::invalid_argument(std::string(settings.fibers ? "fiber glyphs" : "field fiber_strain") +
                                  ": the frame has no per-element fibers");
    if (f.dm_inv && f.dm_inv->size() != ne) throw std::invalid_argument("frame: dm_inv has the wrong size");
  }

  core::Mat3 deformation(const FrameView& f, int surface_element) const {
    const int e = surface.surface_elements()[static_cast<size_t>(surface_element)];
    const core::Mat3& Dm_inv = f.dm_inv ? (*f.dm_inv)[static_cast<size_t>(e)] : surface.surface_dm_inv()[static_cast<size_t>(surface_element)];
    return core::deformation_gradient(core::gather(f.x, mesh.tets()[static_cast<size_t>(e)]), Dm_inv);
  }

  void update_range(double vmin, double vmax) {
    if (settings.range || settings.field == Field::activation || !is_scalar(settings.field)) return;
    if (settings.field == Field::displacement) vmin = 0;
    vmin = std::min(vmin, 0.0), vmax = std::max(vmax, 0.0);
    if (!have_envelope) lo = vmin, hi = vmax, have_envelope = true;
    lo = std::min(lo, vmin), hi = std::max(hi, vmax);
    if (hi - lo < 1e-12) hi = lo + 1e-12;
  }

  void prepare(const FrameView& f) {
    const auto& tris = surface.triangles();
    const auto& tse = surface.triangle_surface_element();
    const int T = surface.num_triangles();
    const Field field = settings.field;
    // Field values: per surface element or per node.
    double vmin = HUGE_VAL, vmax = -HUGE_VAL;
    const auto& se = surface.surface_elements();
    if (field == Field::activation || field == Field::fiber_strain) {
      element_values.resize(se.size());
      for (size_t i = 0; i < se.size(); ++i) {
        const size_t e = static_cast<size_t>(se[i]);
        element_values[i] = field == Field::activation ? (*f.activation)[e]
                                                       : (deformation(f, static_cast<int>(i)) * (*f.fibers)[e]).norm() - 1.0;
        vmin = std::min(vmin, element_values[i]), vmax = std::max(vmax, element_values[i]);
      }
    } else if (field == Field::displacement) {
      node_values.assign(static_cast<size_t>(mesh.num_nodes()), 0.0);
      for (const core::Tri& t : tris)
        for (int v : t) {
          const double u = (f.x.col(v) - mesh.rest_positions().col(v)).norm();
          node_values[static_cast<size_t>(v)] = u;
          vmin = std::min(vmin, u), vmax = std::max(vmax, u);
        }
    }
    if (vmin <= vmax) update_range(vmin, vmax);
    // Smooth per-element fields: each surface node takes the mean over its triangles.
    const bool smooth = settings.smooth && (field == Field::activation || field == Field::fiber_strain);
    if (smooth) {
      node_values.assign(static_cast<size_t>(mesh.num_nodes()), 0.0);
      node_weights.assign(static_cast<size_t>(mesh.num_nodes()), 0.0);
      for (int t = 0; t < T; ++t)
        for (int v : tris[static_cast<size_t>(t)]) {
          node_values[static_cast<size_t>(v)] += element_values[static_cast<size_t>(tse[static_cast<size_t>(t)])];
          node_weights[static_cast<size_t>(v)] += 1;
        }
      for (size_t v = 0; v < node_values.size(); ++v)
        if (node_weights[v] > 0) node_values[v] /= node_weights[v];
    }
    const double scale = 1.0 / (hi - lo);
    colours.resize(static_cast<size_t>(T) * 12);
    vertices.resize(3, 3 * T);
    for (int t = 0; t < T; ++t) {
      for (int k = 0; k < 3; ++k) {
        const int v = tris[static_cast<size_t>(t)][static_cast<size_t>(k)];
        vertices.col(3 * t + k) = f.x.col(v).cast<float>();
        Rgba c = plain_colour();
        switch (field) {
          case Field::activation:
          case Field::fiber_strain:
            c = viridis(((smooth ? node_values[static_cast<size_t>(v)] : element_values[static_cast<size_t>(tse[static_cast<size_t>(t)])]) - lo) * scale);
            break;
          case Field::displacement: c = viridis((node_values[static_cast<size_t>(v)] - lo) * scale); break;
          case Field::region: c = region_colour(mesh.regions()[static_cast<size_t>(surface.triangle_elements()[static_cast<size_t>(t)])]); break;
          case Field::none: break;
        }
        std::uint8_t* p = &colours[static_cast<size_t>(12 * t + 4 * k)];
        p[0] = c.r, p[1] = c.g, p[2] = c.b, p[3] = 255;
      }
    }
    surface.corner_normals(f.x, normals);
    // Fiber glyphs: a segment through each surface triangle's centroid along F f, laid
    // into the triangle's plane, lifted off it by a small fraction of an edge.
    glyphs.clear();
    glyph_colours.clear();
    if (settings.fibers) {
      const double len = settings.fiber_length * surface.mean_edge_m();
      std::vector<core::Vec3> dir(se.size());
      for (size_t i = 0; i < se.size(); ++i) dir[i] = (deformation(f, static_cast<int>(i)) * (*f.fibers)[static_cast<size_t>(se[i])]).normalized();
      glyphs.reserve(static_cast<size_t>(T) * 6);
      const int stride = (T + settings.max_fiber_glyphs - 1) / settings.max_fiber_glyphs;
      for (int t = 0; t < T; t += stride) {
        const core::Tri& tri = tris[static_cast<size_t>(t)];
        const core::Vec3 a = f.x.col(tri[0]), b = f.x.col(tri[1]), c = f.x.col(tri[2]);
        const core::Vec3 n = (b - a).cross(c - a).normalized();
        const core::Vec3 d0 = dir[static_cast<size_t>(tse[static_cast<size_t>(t)])];
        const core::Vec3 dt = d0 - d0.dot(n) * n;
        if (dt.norm() < 0.5) continue;  // the fiber crosses this face (more than 60 deg from its plane)
        const core::Vec3 d = dt.normalized();
        const core::Vec3 m = (a + b + c) / 3.0 + 0.03 * surface.mean_edge_m() * n;
        for (const core::Vec3& p : {core::Vec3(m - 0.5 * len * d), core::Vec3(m + 0.5 * len * d)})
          for (int k = 0; k < 3; ++k) glyphs.push_back(static_cast<float>(p[k]));
        // Dark glyphs on light colours, light ones on dark colours (luma of the face).
        const std::uint8_t* face = &colours[static_cast<size_t>(12 * t)];
        const std::uint8_t g = 0.299 * face[0] + 0.587 * face[1] + 0.114 * face[2] > 110 ? 20 : 235;
        for (int k = 0; k < 8; ++k) glyph_colours.push_back(k % 4 == 3 ? 255 : g);
      }
    }
  }

  void draw() {
    const int W = context.width(), H = context.height();
    glViewport(0, 0, W, H);
    const Rgba bg = settings.background;
    glClearColor(bg.r / 255.f, bg.g / 255.f, bg.b / 255.f, 1.f);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    // Clip planes around the current bounding sphere.
    const Eigen::Vector3f lo_x = vertices.rowwise().minCoeff(), hi_x = vertices.rowwise().maxCoeff();
    const core::Vec3 centre = (0.5f * (lo_x + hi_x)).cast<double>();
    const double r = 0.5 * (hi_x - lo_x).cast<double>().norm() * 1.02 + 1e-9;
    const double dist = (centre - camera.eye).dot((camera.target - camera.eye).normalized());
    double near_m = dist - r, far_m = dist + r;
    if (!camera.orthographic) near_m = std::max(near_m, 1e-4 * far_m);
    const Eigen::Matrix4d P = camera.projection(static_cast<double>(W) / H, near_m, far_m), V = camera.view();
    glMatrixMode(GL_PROJECTION);
    glLoadMatrixd(P.data());
    glMatrixMode(GL_MODELVIEW);
    glLoadMatrixd(V.data());
    glEnable(GL_DEPTH_TEST);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.f, 1.f);

    const float key[3] = {-0.35f, 0.55f, 0.76f}, fill[3] = {0.8f, -0.15f, 0.58f};
    float dirs[6];
    for (int k = 0; k < 3; ++k) dirs[k] = key[k], dirs[3 + k] = fill[k];
    for (int l = 0; l < 2; ++l) {
      const float n = std::sqrt(dirs[3 * l] * dirs[3 * l] + dirs[3 * l + 1] * dirs[3 * l + 1] + dirs[3 * l + 2] * dirs[3 * l + 2]);
      for (int k = 0; k < 3; ++k) dirs[3 * l + k] /= n;
    }
    const float power[2] = {0.62f, 0.28f}, ambient = 0.32f, specular = 0.18f;
    if (settings.per_pixel_lighting) {
      glUseProgram(program);
      glUniform3fv(glGetUniformLocation(program, "light_dir"), 2, dirs);
      glUniform1fv(glGetUniformLocation(program, "light_power"), 2, power);
      glUniform1f(glGetUniformLocation(program, "ambient"), ambient);
      glUniform1f(glGetUniformLocation(program, "specular"), specular);
      glUniform1f(glGetUniformLocation(program, "orthographic"), camera.orthographic ? 1.f : 0.f);
    } else {
      // The same two lights in OpenGL's fixed-function pipeline (per vertex). Directions
      // are given in eye space: load the identity before setting them.
      glPushMatrix();
      glLoadIdentity();
      glEnable(GL_LIGHTING);
      glEnable(GL_NORMALIZE);
      const float amb[4] = {ambient, ambient, ambient, 1.f};
      glLightModelfv(GL_LIGHT_MODEL_AMBIENT, amb);
      for (int l = 0; l < 2; ++l) {
        const GLenum light = GL_LIGHT0 + static_cast<GLenum>(l);
        const float pos[4] = {dirs[3 * l], dirs[3 * l + 1], dirs[3 * l + 2], 0.f};
        const float diffuse[4] = {power[l], power[l], power[l], 1.f}, spec[4] = {power[l] * specular, power[l] * specular, power[l] * specular, 1.f};
        const float none[4] = {0.f, 0.f, 0.f, 1.f};
        glEnable(light);
        glLightfv(light, GL_POSITION, pos);
        glLightfv(light, GL_DIFFUSE, diffuse);
        glLightfv(light, GL_SPECULAR, spec);
        glLightfv(light, GL_AMBIENT, none);
      }
      glPopMatrix();
      const float white[4] = {1.f, 1.f, 1.f, 1.f};
      glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, white);
      glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 40.f);
      glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
      glEnable(GL_COLOR_MATERIAL);
      glShadeModel(GL_SMOOTH);
    }
    glEnableClientState(GL_VERTEX_ARRAY);
    glEnableClientState(GL_NORMAL_ARRAY);
    glEnableClientState(GL_COLOR_ARRAY);
    glVertexPointer(3, GL_FLOAT, 0, vertices.data());
    glNormalPointer(GL_FLOAT, 0, normals.data());
    glColorPointer(4, GL_UNSIGNED_BYTE, 0, colours.data());
    glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(vertices.cols()));
    glDisableClientState(GL_NORMAL_ARRAY);
    glDisableClientState(GL_COLOR_ARRAY);
    glUseProgram(0);
    glDisable(GL_LIGHTING);
    if (!glyphs.empty()) {
      glLineWidth(1.4f * static_cast<float>(settings.supersample));
      glEnableClientState(GL_COLOR_ARRAY);
      glVertexPointer(3, GL_FLOAT, 0, glyphs.data());
      glColorPointer(4, GL_UNSIGNED_BYTE, 0, glyph_colours.data());
      glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(glyphs.size() / 3));
      glDisableClientState(GL_COLOR_ARRAY);
    }
    glDisableClientState(GL_VERTEX_ARRAY);
    glFinish();
  }

  void readback() {
    const int ss = settings.supersample;
    if (ss == 1) {
      image.width = context.width(), image.height = context.height();
      image.rgba.resize(static_cast<size_t>(image.width) * static_cast<size_t>(image.height) * 4);
      std::memcpy(image.rgba.data(), context.pixels(), image.rgba.size());
      return;
    }
    Image big;
    big.width = context.width(), big.height = context.height();
    big.rgba.assign(context.pixels(), context.pixels() + static_cast<size_t>(big.width) * static_cast<size_t>(big.height) * 4);
    image = downscale(big, settings.width, settings.height);
  }

  void overlay(const FrameView& f) {
    if (settings.colour_bar) {
      if (is_scalar(settings.field)) draw_colour_bar(image, font, settings.field, lo, hi, settings.text);
      else if (settings.field == Field::region) draw_region_legend(image, font, mesh.num_regions(), settings.text);
    }
    if (settings.caption && !f.caption.empty()) draw_caption(image, font, f.caption, settings.text);
    if (settings.pv_inset && f.pv_loop && !f.pv_loop->empty()) draw_pv_inset(image, font, *f.pv_loop, settings.text);
  }
};

Renderer::Renderer(const core::TetMesh& mesh, RenderSettings settings) {
  settings.validate();
  impl_ = std::make_unique<Impl>(mesh, settings);
}

Renderer::~Renderer() = default;

void Renderer::set_camera(const Camera& camera) {
  camera.validate();
  impl_->camera = camera;
}

const Camera& Renderer::camera() const { return impl_->camera; }
const RenderSettings& Renderer::settings() const { return impl_->settings; }
std::pair<double, double> Renderer::range() const { return {impl_->lo, impl_->hi}; }
const RenderTimes& Renderer::last_times() const { return impl_->times; }
std::string Renderer::describe() const { return impl_->context.describe(); }

const Image& Renderer::render(const FrameView& frame) {
  Impl& m = *impl_;
  m.check(frame);
  m.context.make_current();
  const auto t0 = Clock::now();
  m.prepare(frame);
  const auto t1 = Clock::now();
  m.draw();
  const auto t2 = Clock::now();
  m.readback();
  const auto t3 = Clock::now();
  m.overlay(frame);
  m.times = {std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t2 - t1).count(),
             std::chrono::duration<double>(t3 - t2).count(), since(t3), since(t0)};
  return m.image;
}

}  // namespace fiberfem::render
