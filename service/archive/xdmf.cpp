// The XDMF sidecar of an archive (ParaView, meshio): written atomically, next to the file.

#include "service/archive/archive_internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace fiberfem::archive {

using namespace detail;

// ---------------------------------------------------------------------------- sidecars

namespace detail {

void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw std::runtime_error("archive: cannot write '" + tmp + "'");
    f << text;
    if (!f) throw std::runtime_error("archive: cannot write '" + tmp + "'");
  }
  std::filesystem::rename(tmp, path);
}

std::string sidecar_path(const std::string& h5_path) {
  const std::filesystem::path p(h5_path);
  return (p.parent_path() / p.stem()).string() + ".xdmf";
}

}  // namespace detail

namespace detail {
// The sidecar's text for F frames (their times) of an archive of N nodes per frame and E
// elements, of 10 nodes each when `order2` (Tetrahedron_10 from /mesh/order2_tets).
std::string xdmf_text(const std::string& h5_path, long F, const std::vector<double>& times, hsize_t N, hsize_t E, bool velocities,
                      bool displacement, bool order2) {
  const std::string file = std::filesystem::path(h5_path).filename().string();
  const std::string n = std::to_string(N), e = std::to_string(E), f = std::to_string(F);
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<!-- fiberfem run archive sidecar (docs/archive.md); data stay in " << file
    << " -->\n<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n<Domain>\n"
    << "<Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const auto slab = [&](const std::string& ds, long i, bool vec) {
    // file.h5:/path|start:stride:count:dims (ParaView's Xdmf3 hyperslab syntax)
    const std::string s = std::to_string(i);
    return vec ? file + ":/frames/" + ds + "|" + s + " 0 0:1 1 1:1 " + n + " 3:" + f + " " + n + " 3"
               : file + ":/frames/" + ds + "|" + s + " 0:1 1:1 " + e + ":" + f + " " + e;
  };
  for (long i = 0; i < F; ++i) {
    x << "<Grid Name=\"frame " << i << "\" GridType=\"Uniform\">\n<Time Value=\"" << times[static_cast<size_t>(i)] << "\"/>\n"
      << "<Topology TopologyType=\"" << (order2 ? "Tetrahedron_10" : "Tetrahedron") << "\" NumberOfElements=\"" << e << "\">\n"
      << " <DataItem Dimensions=\"" << e << (order2 ? " 10" : " 4") << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">"
      << file << (order2 ? ":/mesh/order2_tets" : ":/mesh/tets") << "</DataItem>\n</Topology>\n"
      << "<Geometry GeometryType=\"XYZ\">\n <DataItem Dimensions=\"" << n
      << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("positions", i, true)
      << "</DataItem>\n</Geometry>\n";
    if (displacement)
      x << "<Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem Dimensions=\"" << n
        << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("displacement", i, true)
        << "</DataItem>\n</Attribute>\n";
    if (velocities)
      x << "<Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem Dimensions=\"" << n
        << " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("velocities", i, true)
        << "</DataItem>\n</Attribute>\n";
    x << "<Attribute Name=\"activation\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem Dimensions=\"" << e
      << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << slab("activation", i, false)
      << "</DataItem>\n</Attribute>\n"
      << "<Attribute Name=\"region\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem Dimensions=\"" << e
      << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" << file << ":/mesh/regions</DataItem>\n</Attribute>\n"
      << "</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  return x.str();
}

}  // namespace detail

void write_xdmf(const std::string& h5_path) {
  long F = 0;
  std::vector<double> times;
  bool velocities = false, displacement = false, order2 = false;
  hsize_t N = 0, E = 0;
  {
    ArchiveReader r(h5_path, /*follow=*/true);
    F = r.frames();
    times = r.times();
    velocities = r.header().has_velocities;
    displacement = r.header().has_displacement;
    order2 = r.header().order == 2;
    N = static_cast<hsize_t>(order2 ? r.header().element_rest_positions.cols() : r.header().rest_positions.cols());
    E = r.header().tets.size();
  }
  write_atomically(sidecar_path(h5_path), detail::xdmf_text(h5_path, F, times, N, E, velocities, displacement, order2));
}


}  // namespace fiberfem::archive
