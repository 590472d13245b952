// Tools on archive files: recover (after a crash of the writer), export for meshio, the
// circulation as CSV.

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

long recover(const std::string& h5_path) {
  h5::silence_errors();
  if (H5Fis_hdf5(h5_path.c_str()) <= 0) throw std::runtime_error("'" + h5_path + "' is not an HDF5 file (or cannot be read)");
  {
    // What h5clear --status does: open read-write with the file access property that
    // clears the consistency flags a SWMR writer leaves set when it dies.
    h5::Handle fapl = h5::latest_format_access();
    hbool_t clear = 1;
    h5::check(H5Pset(fapl.id(), "clear_status_flags", &clear), "cannot ask to clear the status flags of '" + h5_path + "'");
    h5::Handle f(H5Fopen(h5_path.c_str(), H5F_ACC_RDWR, fapl.id()), H5Fclose,
                 "cannot open '" + h5_path + "' to clear its status flags");
    h5::write_attribute(f.id(), "recovered_utc", utc_now());
  }
  long frames = 0;
  {
    ArchiveReader r(h5_path, /*follow=*/false);  // an ordinary open must work now
    frames = r.frames();
    if (frames > 0) (void)r.frame(frames - 1);
  }
  write_xdmf(h5_path);
  return frames;
}

void export_meshio(const std::string& h5_path, const std::string& out_xdmf) {
  ArchiveReader r(h5_path, /*follow=*/true);
  const ArchiveHeader& h = r.header();
  const std::filesystem::path xp(out_xdmf);
  const std::string data_path = (xp.parent_path() / xp.stem()).string() + ".h5";
  if (std::filesystem::exists(data_path) && std::filesystem::equivalent(data_path, h5_path))
    throw std::invalid_argument("archive: export-meshio would overwrite the archive '" + h5_path + "'");
  const std::string file = std::filesystem::path(data_path).filename().string();
  // An order-2 run exports its 10-node mesh (meshio's tetra10), every node of it.
  const bool order2 = h.order == 2;
  const core::Positions& rest = order2 ? h.element_rest_positions : h.rest_positions;
  const hsize_t N = static_cast<hsize_t>(rest.cols()), E = h.tets.size(), K = order2 ? 10 : 4;
  h5::File out = h5::File::create(data_path);
  h5::create_fixed<double>(out.id(), "points", {N, 3}, rest.data());
  std::vector<std::int64_t> cells;
  if (order2)
    for (const auto& t : h.element_tets) cells.insert(cells.end(), t.begin(), t.end());
  else
    for (const core::Tet& t : h.tets) cells.insert(cells.end(), t.begin(), t.end());
  h5::create_fixed<std::int64_t>(out.id(), "cells", {E, K}, cells.data());
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n<Domain>\n"
    << "<Grid Name=\"mesh\" GridType=\"Uniform\">\n<Geometry GeometryType=\"XYZ\">\n <DataItem DataType=\"Float\" Dimensions=\"" << N
    << " 3\" Format=\"HDF\" Precision=\"8\">" << file << ":/points</DataItem>\n</Geometry>\n"
    << "<Topology TopologyType=\"" << (order2 ? "Tetrahedron_10" : "Tetrahedron") << "\" NumberOfElements=\"" << E
    << "\">\n <DataItem DataType=\"Int\" Dimensions=\"" << E << " " << K << "\" Format=\"HDF\" Precision=\"8\">" << file
    << ":/cells</DataItem>\n</Topology>\n</Grid>\n"
    << "<Grid Name=\"TimeSeries\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const long F = r.frames();
  for (long i = 0; i < F; ++i) {
    const Frame fr = r.frame(i);
    const core::Positions& at = order2 ? fr.element_positions : fr.positions;
    const core::Positions u = at - rest;
    const std::string s = std::to_string(i);
    h5::create_fixed<double>(out.id(), "positions_" + s, {N, 3}, at.data());
    h5::create_fixed<double>(out.id(), "displacement_" + s, {N, 3}, u.data());
    h5::create_fixed<double>(out.id(), "activation_" + s, {E}, fr.activation_pa.data());
    x << "<Grid Name=\"frame " << s << "\">\n<xi:include xpointer=\"xpointer(//Grid[@Name=&quot;mesh&quot;]/*[self::Topology or "
         "self::Geometry])\"/>\n<Time Value=\""
      << fr.time_s << "\"/>\n";
    for (const char* name : {"positions", "displacement"})
      x << "<Attribute Name=\"" << name << "\" AttributeType=\"Vector\" Center=\"Node\">\n <DataItem DataType=\"Float\" Dimensions=\""
        << N << " 3\" Format=\"HDF\" Precision=\"8\">" << file << ":/" << name << "_" << s << "</DataItem>\n</Attribute>\n";
    x << "<Attribute Name=\"activation\" AttributeType=\"Scalar\" Center=\"Cell\">\n <DataItem DataType=\"Float\" Dimensions=\"" << E
      << "\" Format=\"HDF\" Precision=\"8\">" << file << ":/activation_" << s << "</DataItem>\n</Attribute>\n</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  out.close();
  write_atomically(out_xdmf, x.str());
}


long export_circulation_csv(const std::string& h5_path, const std::string& out_csv) {
  const ArchiveReader r(h5_path, /*follow=*/true);
  const std::vector<std::string>& columns = r.header().circulation_columns;
  if (columns.empty()) throw std::runtime_error("'" + h5_path + "' has no circulation (its scene has no circulation key, or it was written before archives kept one)");
  std::ofstream out(out_csv);
  if (!out) throw std::runtime_error("cannot write '" + out_csv + "'");
  out << "step";
  for (const std::string& c : core::circulation::snapshot_columns()) out << "," << c;
  out << "\n";
  char number[32];
  for (long i = 0; i < r.frames(); ++i) {
    const Frame f = r.frame(i);
    out << f.step;
    for (double v : core::circulation::to_columns(*f.circulation)) {
      std::snprintf(number, sizeof number, "%.17g", v);
      out << "," << number;
    }
    out << "\n";
  }
  if (!out) throw std::runtime_error("writing '" + out_csv + "' failed");
  return r.frames();
}

}  // namespace fiberfem::archive
