// The circulation's wire type (idl/circulation.idl) and its record (idl/records.hpp): its
// members after run_id and frame are the snapshot's columns, in order, and a record goes
// through a sample and back unchanged (the integer members carry whole numbers).
#include "idl/records.hpp"

#include <gtest/gtest.h>

namespace cc = fiberfem::core::circulation;
namespace dds = fiberfem::dds;

TEST(CirculationRecord, MembersAreTheSnapshotColumnsInOrder) {
  EXPECT_EQ(dds::circulation_members(), cc::snapshot_columns());
}

TEST(CirculationRecord, GoesThroughASampleAndBack) {
  dds::Circulation r;
  r.run_id = "run-7";
  r.frame = 1234567890123ul;
  std::vector<double> numbers(cc::snapshot_columns().size());
  for (size_t i = 0; i < numbers.size(); ++i) numbers[i] = 0.1 * static_cast<double>(i) + 1e-7;
  r.snapshot = cc::from_columns(cc::snapshot_columns(), numbers.data());
  r.snapshot.pressure_iterations = 5;
  r.snapshot.last_beat.index = 3;
  bool written = false;
  dds::with_sample(r, [&](const fiberfem_CirculationState& s) {
    written = true;
    EXPECT_STREQ(s.run_id, "run-7");
    EXPECT_EQ(s.frame, r.frame);
    EXPECT_EQ(s.lv_pressure_pa, r.snapshot.chamber_pressure_pa[cc::lv]);
    EXPECT_EQ(s.aortic_flow_m3_s, r.snapshot.valve_flow_m3_s[cc::aortic]);
    EXPECT_EQ(s.pressure_iterations, 5);
    EXPECT_EQ(s.beat, 3);
    const dds::Circulation back = dds::to_record(s);
    EXPECT_EQ(back.run_id, r.run_id);
    EXPECT_EQ(back.frame, r.frame);
    EXPECT_EQ(cc::to_columns(back.snapshot), cc::to_columns(r.snapshot));
  });
  EXPECT_TRUE(written);
}
