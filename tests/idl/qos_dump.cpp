// Prints, as JSON, the QoS that Cyclone DDS reports for the topic, the writer and the
// reader of each fiberfem topic as idl/bus.cpp creates them (the policies bus.cpp
// chooses: reliability, durability, history, deadline, liveliness, durability service).
// tests/idl/python_qos_check.py compares the Python client's entities against it.
//
//   idl_qos_dump            (CYCLONEDDS_URI set to the loopback profile)

#include "idl/bus.hpp"

#include <nlohmann/json.hpp>

#include <iostream>

namespace {

using nlohmann::json;
namespace dds = fiberfem::dds;

const char* durability_name(dds_durability_kind_t k) {
  switch (k) {
    case DDS_DURABILITY_VOLATILE: return "volatile";
    case DDS_DURABILITY_TRANSIENT_LOCAL: return "transient_local";
    case DDS_DURABILITY_TRANSIENT: return "transient";
    case DDS_DURABILITY_PERSISTENT: return "persistent";
  }
  return "?";
}

json history_of(dds_history_kind_t kind, int32_t depth) {
  return kind == DDS_HISTORY_KEEP_ALL ? json{"keep_all"} : json{"keep_last", depth};
}

// The chosen policies of one entity, with Cyclone's defaults where a policy is unset
// (infinite deadline and lease, the default durability service).
json policies(dds_entity_t entity) {
  dds_qos_t* q = dds_create_qos();
  dds::check(dds_get_qos(entity, q), "dds_get_qos");
  json j;
  dds_reliability_kind_t rel = DDS_RELIABILITY_BEST_EFFORT;
  dds_duration_t blocking = 0;
  if (dds_qget_reliability(q, &rel, &blocking))
    j["reliability"] = {rel == DDS_RELIABILITY_RELIABLE ? "reliable" : "best_effort", blocking};
  dds_durability_kind_t dur = DDS_DURABILITY_VOLATILE;
  if (dds_qget_durability(q, &dur)) j["durability"] = durability_name(dur);
  dds_history_kind_t hist = DDS_HISTORY_KEEP_LAST;
  int32_t depth = 1;
  if (dds_qget_history(q, &hist, &depth)) j["history"] = history_of(hist, depth);
  dds_duration_t deadline = DDS_INFINITY;
  dds_qget_deadline(q, &deadline);
  j["deadline"] = deadline;
  dds_liveliness_kind_t live = DDS_LIVELINESS_AUTOMATIC;
  dds_duration_t lease = DDS_INFINITY;
  dds_qget_liveliness(q, &live, &lease);
  j["liveliness"] = {live == DDS_LIVELINESS_AUTOMATIC ? "automatic" : "manual", lease};
  dds_duration_t cleanup = 0;
  dds_history_kind_t ds_hist = DDS_HISTORY_KEEP_LAST;
  int32_t ds_depth = 1, max_samples = -1, max_instances = -1, max_per_instance = -1;
  dds_qget_durability_service(q, &cleanup, &ds_hist, &ds_depth, &max_samples, &max_instances, &max_per_instance);
  j["durability_service"] = {cleanup, history_of(ds_hist, ds_depth), max_samples, max_instances, max_per_instance};
  dds_delete_qos(q);
  return j;
}

template <class T>
json topic_entities(const dds::Participant& pp) {
  dds::Writer<T> writer(pp);
  dds::Reader<T> reader(pp);
  return {{"name", dds::topic_name(dds::TopicOf<T>::topic)},
          {"topic", policies(dds_get_topic(writer.get()))},
          {"writer", policies(writer.get())},
          {"reader", policies(reader.get())}};
}

}  // namespace

int main() {
  try {
    const dds::Participant pp;
    const json out = {{"topology", topic_entities<fiberfem_MeshTopology>(pp)},
                      {"state", topic_entities<fiberfem_MeshState>(pp)},
                      {"command", topic_entities<fiberfem_Command>(pp)},
                      {"ack", topic_entities<fiberfem_CommandAck>(pp)},
                      {"status", topic_entities<fiberfem_ServiceStatus>(pp)},
                      {"circulation", topic_entities<fiberfem_CirculationState>(pp)}};
    std::cout << out.dump(2) << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "idl_qos_dump: " << e.what() << "\n";
    return 1;
  }
}
