#include "clients/render/font.hpp"

#include <ft2build.h>
#include FT_FREETYPE_H

#include <cstdlib>
#include <stdexcept>

namespace fiberfem::render {

std::string default_font_path() {
  if (const char* env = std::getenv("FIBERFEM_FONT"); env && *env) return env;
  return FIBERFEM_FONT_FILE;
}

struct Font::Library {
  FT_Library lib = nullptr;
  FT_Face face = nullptr;
  ~Library() {
    if (face) FT_Done_Face(face);
    if (lib) FT_Done_FreeType(lib);
  }
};

Font::Font(int pixel_size, const std::string& path) : ft_(std::make_unique<Library>()), size_(pixel_size) {
  if (pixel_size < 4 || pixel_size > 512) throw std::invalid_argument("font size " + std::to_string(pixel_size) + " px is outside [4, 512]");
  if (FT_Init_FreeType(&ft_->lib) != 0) throw std::runtime_error("FreeType: cannot initialise");
  if (FT_New_Face(ft_->lib, path.c_str(), 0, &ft_->face) != 0)
    throw std::runtime_error("cannot open font " + path + " (install fonts-dejavu-core or set FIBERFEM_FONT)");
  FT_Set_Pixel_Sizes(ft_->face, 0, static_cast<FT_UInt>(pixel_size));
  ascent_ = glyph('H').top;
}

Font::~Font() = default;

const Font::Glyph& Font::glyph(char c) {
  if (c < 32 || c > 126) c = '?';
  auto it = cache_.find(c);
  if (it != cache_.end()) return it->second;
  Glyph g;
  if (FT_Load_Char(ft_->face, static_cast<FT_ULong>(static_cast<unsigned char>(c)), FT_LOAD_RENDER) == 0) {
    const FT_GlyphSlot s = ft_->face->glyph;
    g.left = s->bitmap_left, g.top = s->bitmap_top;
    g.width = static_cast<int>(s->bitmap.width), g.rows = static_cast<int>(s->bitmap.rows);
    g.advance = static_cast<int>(s->advance.x >> 6);
    g.coverage.resize(static_cast<size_t>(g.width) * static_cast<size_t>(g.rows));
    for (int y = 0; y < g.rows; ++y)
      for (int x = 0; x < g.width; ++x)
        g.coverage[static_cast<size_t>(y * g.width + x)] = s->bitmap.buffer[y * s->bitmap.pitch + x];
  }
  return cache_.emplace(c, std::move(g)).first->second;
}

int Font::text_width(const std::string& text) {
  int w = 0;
  for (char c : text) w += glyph(c).advance;
  return w;
}

void Font::draw(Image& image, int x, int baseline_y, const std::string& text, Rgba colour) {
  for (char c : text) {
    const Glyph& g = glyph(c);
    for (int y = 0; y < g.rows; ++y)
      for (int i = 0; i < g.width; ++i) {
        const std::uint8_t a = g.coverage[static_cast<size_t>(y * g.width + i)];
        if (a) image.blend(x + g.left + i, baseline_y - g.top + y, colour, a / 255.0);
      }
    x += g.advance;
  }
}

}  // namespace fiberfem::render
