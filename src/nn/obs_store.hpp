// The observation fields, written once, and ObsStore: the one owner of observation arrays in the float layout
// the networks read (ObsBatch), for any number of agent rows.
//
// HNS_OBS_FIELDS lists every observation array an agent row has, X(name, member, type, axis, key):
//   name    the field's name from the simulator on: batch::BatchState's field (the batch checks its fields
//           against this list at compile time, ppo/batch_obs.hpp), StepObs's pointer, the Python module's
//           observation key;
//   member  the network's name for it: the ObsBatch pointer and the ObsStore array (floats, masks widened);
//   type    the element type in the simulator's layout (masks are 0/1 bytes there);
//   axis    its entity axis (ObsAxis), or kObsRowAxis for one row of features per agent;
//   key     the normaliser key (ObsKey) of a feature field, kObsMaskKey for a mask.
// Per agent row a field holds entities(axis) x features(key) values (a mask: one per entity). The list's
// order is ObsBatch's: features in key order, then the policy's masks, then the value net's.
#pragma once

#include "nn/actor_critic.hpp"
#include "nn/obs_normalizer.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#define HNS_OBS_FIELDS(X)                                                   \
  X(obs_self, self, float, kObsRowAxis, kObsSelf)                           \
  X(lidar, lidar, float, kObsRowAxis, kObsLidar)                            \
  X(obs_agents, agents, float, kObsAgentAxis, kObsAgents)                   \
  X(obs_boxes, boxes, float, kObsBoxAxis, kObsBoxes)                        \
  X(obs_ramps, ramps, float, kObsRampAxis, kObsRamps)                       \
  X(obs_sites, sites, float, kObsSiteAxis, kObsSites)                       \
  X(mask_agents, agents_seen, uint8_t, kObsAgentAxis, kObsMaskKey)          \
  X(mask_boxes, boxes_seen, uint8_t, kObsBoxAxis, kObsMaskKey)              \
  X(mask_ramps, ramps_seen, uint8_t, kObsRampAxis, kObsMaskKey)             \
  X(mask_sites, sites_seen, uint8_t, kObsSiteAxis, kObsMaskKey)             \
  X(value_mask_agents, agents_present, uint8_t, kObsAgentAxis, kObsMaskKey) \
  X(value_mask_boxes, boxes_present, uint8_t, kObsBoxAxis, kObsMaskKey)     \
  X(value_mask_ramps, ramps_present, uint8_t, kObsRampAxis, kObsMaskKey)    \
  X(value_mask_sites, sites_present, uint8_t, kObsSiteAxis, kObsMaskKey)

namespace hns::nn {

// The entity axis of an observation field: none (one row per agent), the other agents, boxes, ramps, sites.
enum ObsAxis : int { kObsRowAxis, kObsAgentAxis, kObsBoxAxis, kObsRampAxis, kObsSiteAxis };
// The key column of a mask field (masks are not normalised).
inline constexpr int kObsMaskKey = -1;

// One row of HNS_OBS_FIELDS.
struct ObsField {
  const char* name;    // BatchState's
  const char* member;  // ObsBatch's
  bool mask;
  ObsAxis axis;
  int key;  // ObsKey, or kObsMaskKey
};
// The ObsField of one X(...) of the list.
#define HNS_OBS_FIELD_INFO(name, member, type, axis, key)    \
  ::hns::nn::ObsField {                                      \
#name, #member, key == ::hns::nn::kObsMaskKey, axis, key \
  }
inline constexpr ObsField kObsFieldList[] = {
#define HNS_OBS_FIELD_ROW(...) HNS_OBS_FIELD_INFO(__VA_ARGS__),
    HNS_OBS_FIELDS(HNS_OBS_FIELD_ROW)
#undef HNS_OBS_FIELD_ROW
};

// Entities along an axis (1 for kObsRowAxis) and features per entity of a normaliser key (1 for a mask).
int axis_entities(const ObsShape& s, ObsAxis axis);
int key_features(const ObsShape& s, int key);
// A field's values per agent row, and its dimensions per agent row (the entity axis unless kObsRowAxis, then
// the features unless a mask): obs_agents [A - 1, agent_features], lidar [lidar_rays], mask_boxes [B].
inline size_t row_values(const ObsShape& s, const ObsField& f) {
  return size_t(axis_entities(s, f.axis)) * size_t(key_features(s, f.key));
}
std::vector<int> row_dims(const ObsShape& s, const ObsField& f);

// One step's observations in the simulator's layout (features float, masks 0/1 bytes), `rows` agent rows,
// wherever they are held: a batch's state (ppo::StepObsView::of) or arrays a caller owns (the Python
// module's Policy.act). A field of no values (the sites of a scene without them) may be null.
struct StepObs {
#define HNS_OBS_STEP_POINTER(name, member, type, axis, key) const type* name = nullptr;
  HNS_OBS_FIELDS(HNS_OBS_STEP_POINTER)
#undef HNS_OBS_STEP_POINTER

  // The feature arrays by normaliser key from agent row `row` on (null where a pointer is null): the rows
  // ObsNormalizer::add_rows reads.
  std::array<const float*, kNumObsKeys> features_from(size_t row, const ObsShape& s) const;
};

// Observation arrays of `rows` agent rows in the networks' float layout: the trainer's rollout (T x G rows,
// normalised as copied), a policy's step, the benchmarks' and tests' synthetic observations.
class ObsStore {
 public:
  ObsStore() = default;
  ObsStore(const ObsShape& shape, size_t rows) { allocate(shape, rows); }

  // Sizes (and zeroes) every array for `rows` rows of this shape.
  void allocate(const ObsShape& shape, size_t rows);
  // Floats per row over all the arrays, the reset flag included (what allocate takes per row).
  static size_t floats_per_row(const ObsShape& shape);
  const ObsShape& shape() const { return shape_; }
  size_t rows() const { return rows_; }

  // Copies one step's observations and masks (rows agent rows) into rows [row0, row0 + rows), normalised and
  // clipped on the way when `norm` is given (the networks then read them with ObsNormView::identity());
  // masks widened to floats; the reset flags are left to the caller.
  void copy_step(const StepObs& step, size_t rows, size_t row0, const ObsNormView* norm = nullptr);
  // Views of every array (null for an array of no values).
  ObsBatch batch() const;

  // The arrays, named as ObsBatch's, and the reset flags [rows].
#define HNS_OBS_STORE_ARRAY(name, member, type, axis, key) FloatBuffer member;
  HNS_OBS_FIELDS(HNS_OBS_STORE_ARRAY)
#undef HNS_OBS_STORE_ARRAY
  FloatBuffer reset;

 private:
  ObsShape shape_;
  size_t rows_ = 0;
};

}  // namespace hns::nn
