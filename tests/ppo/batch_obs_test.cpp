// One list of observation fields from the batch to the networks: nn's HNS_OBS_FIELDS names BatchState's
// observation fields (every one of them) with the batch's own dimensions in every scene; the batch's field
// dimensions (the Python module's array shapes) come from HNS_BATCH_FIELDS's counts; nn::ObsStore's arrays
// and ObsBatch views have the list's sizes, and a batch step copied into the store is the batch's
// observations.
#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "batch/field_dims.hpp"
#include "batch/scenes.hpp"
#include "nn/obs_store.hpp"
#include "ppo/batch_obs.hpp"

namespace hns::ppo {
namespace {

batch::Layout layout_of(const batch::SceneInfo& scene) {
  batch::BatchConfig config = batch::scene_config(scene.name);
  config.num_envs = 2;
  return batch::Layout::of(config);
}

int64_t product(const std::vector<int64_t>& dims) {
  int64_t p = 1;
  for (int64_t d : dims) p *= d;
  return p;
}

// Every field's dimensions multiply to its count, in every scene; a layout size of 1 stays an axis and a
// per-env scalar has none.
TEST(BatchObs, FieldDimsMultiplyToEachFieldsCount) {
  for (const batch::SceneInfo& scene : batch::kScenes) {
    const batch::Layout L = layout_of(scene);
    using batch::Layout;  // the counts name it
#define HNS_CHECK_DIMS(type, field, count, doc) \
  EXPECT_EQ(product(batch::field_dims(#field, L)), int64_t(count)) << scene.name << " " #field;
    HNS_BATCH_FIELDS(HNS_CHECK_DIMS)
#undef HNS_CHECK_DIMS
  }
  const batch::Layout L = layout_of(batch::kScenes[0]);
  EXPECT_EQ(batch::field_dims("agent_pos", L), (std::vector<int64_t>{L.max_agents, 3}));
  EXPECT_EQ(batch::field_dims("obs_agents", L),
            (std::vector<int64_t>{L.max_agents, L.others, batch::Layout::kAgentFeatures}));
  EXPECT_EQ(batch::field_dims("stat_prep", L), (std::vector<int64_t>{batch::Layout::kPrepStats}));
  EXPECT_TRUE(batch::field_dims("done", L).empty());
  EXPECT_THROW(batch::field_dims("no_such_field", L), std::invalid_argument);
}

// nn's list holds every observation field of the batch (obs_*, mask_*, value_mask_*, lidar) and nothing
// else, and each has the batch's dimensions: max_agents rows of the list's row dimensions.
TEST(BatchObs, ObservationListIsTheBatchsObservationFields) {
  std::set<std::string> batch_obs, listed;
#define HNS_OBS_NAME(type, name, count, doc)                                                   \
  if (std::string(#name).rfind("obs_", 0) == 0 || std::string(#name).rfind("mask_", 0) == 0 || \
      std::string(#name).rfind("value_mask_", 0) == 0 || std::string(#name) == "lidar")        \
    batch_obs.insert(#name);
  HNS_BATCH_FIELDS(HNS_OBS_NAME)
#undef HNS_OBS_NAME
  for (const nn::ObsField& f : nn::kObsFieldList) listed.insert(f.name);
  EXPECT_EQ(listed, batch_obs);
  for (const batch::SceneInfo& scene : batch::kScenes) {
    const batch::Layout L = layout_of(scene);
    const nn::ObsShape shape = obs_shape(L);
    for (const nn::ObsField& f : nn::kObsFieldList) {
      std::vector<int64_t> want{L.max_agents};
      for (int d : nn::row_dims(shape, f)) want.push_back(d);
      if (f.axis == nn::kObsSiteAxis && L.max_sites == 0) continue;  // the batch keeps its site width
      EXPECT_EQ(batch::field_dims(f.name, L), want) << scene.name << " " << f.name;
    }
  }
}

// The store's arrays have the list's sizes, its batch views them (null where empty), and floats_per_row is
// their sum.
TEST(BatchObs, StoreArraysAndViewsHaveTheListsShapes) {
  const batch::Layout L = layout_of(batch::kScenes[0]);
  nn::ObsShape shape = obs_shape(L);
  shape.max_sites = 2, shape.site_features = 4;
  const size_t rows = 5;
  const nn::ObsStore store(shape, rows);
  const nn::ObsBatch b = store.batch();
  size_t floats = 1;
#define HNS_CHECK_ARRAY(name, member, type, axis, key)                                \
  {                                                                                   \
    const nn::ObsField f = HNS_OBS_FIELD_INFO(name, member, type, nn::axis, nn::key); \
    EXPECT_EQ(store.member.size(), rows* nn::row_values(shape, f)) << #member;        \
    EXPECT_EQ(b.member, store.member.data()) << #member;                              \
    floats += store.member.size() / rows;                                             \
  }
  HNS_OBS_FIELDS(HNS_CHECK_ARRAY)
#undef HNS_CHECK_ARRAY
  EXPECT_EQ(store.reset.size(), rows);
  EXPECT_EQ(b.reset, store.reset.data());
  EXPECT_EQ(nn::ObsStore::floats_per_row(shape), floats);
  EXPECT_EQ(store.agents.size(), rows * size_t(shape.num_other_agents()) * size_t(shape.agent_features));
  EXPECT_EQ(store.sites_seen.size(), rows * 2);
  EXPECT_EQ(store.sites.size(), rows * 2 * 4);
  shape.max_sites = 0, shape.site_features = 0;
  const nn::ObsStore no_sites(shape, rows);
  EXPECT_EQ(no_sites.batch().sites, nullptr);
  EXPECT_EQ(no_sites.batch().sites_present, nullptr);
}

// A batch step copied raw is the batch's observations, masks widened to floats, field by field.
TEST(BatchObs, CopiedStepIsTheBatchsObservations) {
  batch::BatchConfig config = batch::scene_config("quadrant");
  config.num_envs = 3;
  batch::BatchSim sim(config);
  sim.reset();
  const batch::BatchState& s = sim.state();
  const nn::ObsShape shape = obs_shape(sim.layout());
  const size_t G = size_t(config.num_envs) * size_t(shape.max_agents);
  nn::ObsStore store(shape, 2 * G);
  store.copy_step(StepObsView::of(s), G, G);
  int compared = 0;
#define HNS_CHECK_COPY(name, member, type, axis, key)                           \
  ASSERT_EQ(store.member.size(), 2 * s.name.size()) << #name;                   \
  for (size_t i = 0; i < s.name.size(); ++i) {                                  \
    ASSERT_EQ(store.member[s.name.size() + i], float(s.name[i])) << #name << i; \
    ASSERT_EQ(store.member[i], 0.0f) << #name << i;                             \
  }                                                                             \
  compared += s.name.size() > 0;
  HNS_OBS_FIELDS(HNS_CHECK_COPY)
#undef HNS_CHECK_COPY
  EXPECT_EQ(compared, 11);  // quadrant has no sites
}

}  // namespace
}  // namespace hns::ppo
