#pragma once
/// @file Text on images through FreeType (anti-aliased glyphs of a TrueType font), for
/// captions and colour-bar labels.

#include "clients/render/image.hpp"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace fiberfem::render {

/// The font file used when none is given: $FIBERFEM_FONT if set, else the build's
/// FIBERFEM_FONT_FILE (DejaVu Sans from fonts-dejavu-core).
std::string default_font_path();

/// A TrueType font at one pixel size, with a cache of rendered glyphs (ASCII 32..126;
/// other bytes draw as '?').
class Font {
 public:
  /// @param pixel_size em height in pixels, in [4, 512].
  /// @throws std::runtime_error naming the file if FreeType cannot open it;
  /// std::invalid_argument for a bad size.
  explicit Font(int pixel_size, const std::string& path = default_font_path());
  ~Font();
  Font(const Font&) = delete;
  Font& operator=(const Font&) = delete;

  /// Em height, pixels.
  int pixel_size() const { return size_; }
  /// Height above the baseline of capitals, pixels.
  int ascent() const { return ascent_; }
  /// Advance width of `text`, pixels.
  int text_width(const std::string& text);
  /// Draws `text` with its baseline at row `baseline_y`, starting at column `x`.
  void draw(Image& image, int x, int baseline_y, const std::string& text, Rgba colour);

 private:
  struct Glyph {
    int left = 0, top = 0, width = 0, rows = 0, advance = 0;
    std::vector<std::uint8_t> coverage;
  };
  const Glyph& glyph(char c);

  struct Library;
  std::unique_ptr<Library> ft_;
  int size_ = 0, ascent_ = 0;
  std::map<char, Glyph> cache_;
};

}  // namespace fiberfem::render
