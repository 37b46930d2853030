// The per-env dimensions of every batch field, read from HNS_BATCH_FIELDS itself: each field's element count
// there is a product of the layout's sizes (L.max_agents, L.others, ...) and constants, one factor per axis.
// Evaluating that same expression with a layout whose sizes are axes yields the axes. A count that is a bare
// constant is one axis of that length, except 1: a per-env scalar (no axis). A layout size of 1 stays an axis
// (lockbox's one agent). The Python module shapes its arrays with this; a new field needs no table.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "batch/batch_sim.hpp"

namespace hns::batch {

namespace field_axes {

struct Axis {
  int64_t n;
};
struct Dims {
  std::vector<int64_t> d;
};
inline Dims operator*(Axis a, Axis b) {
  return {{a.n, b.n}};
}
inline Dims operator*(Axis a, int c) {
  return {{a.n, c}};
}
inline Dims operator*(int c, Axis a) {
  return {{c, a.n}};
}
inline Dims operator*(Dims x, Axis a) {
  x.d.push_back(a.n);
  return x;
}
inline Dims operator*(Dims x, int c) {
  x.d.push_back(c);
  return x;
}
inline Dims dims(Dims x) {
  return x;
}
inline Dims dims(Axis a) {
  return {{a.n}};
}
inline Dims dims(int c) {
  return c == 1 ? Dims{} : Dims{{c}};
}

// Layout's sizes as axes (every size HNS_BATCH_FIELDS names; a count naming another does not compile).
struct AxisLayout {
  explicit AxisLayout(const Layout& L)
      : max_agents{L.max_agents},
        max_boxes{L.max_boxes},
        max_ramps{L.max_ramps},
        max_sites{L.max_sites},
        site_features{L.site_features},
        max_food{L.max_food},
        construction_sites{L.construction_sites},
        others{L.others},
        shape_boxes{L.shape_boxes},
        shape_wedges{L.shape_wedges},
        shape_spheres{L.shape_spheres},
        shape_cylinders{L.shape_cylinders} {}
  Axis max_agents, max_boxes, max_ramps, max_sites, site_features, max_food, construction_sites, others,
      shape_boxes, shape_wedges, shape_spheres, shape_cylinders;
};

}  // namespace field_axes

// Field `name`'s dimensions per env for layout `layout` (their product is the field's count); throws
// std::invalid_argument for a name that is not a field.
inline std::vector<int64_t> field_dims(std::string_view name, const Layout& layout) {
  const field_axes::AxisLayout L(layout);
  using field_axes::dims;
#define HNS_FIELD_DIMS(type, field, count, doc) \
  if (name == #field) return dims(count).d;
  HNS_BATCH_FIELDS(HNS_FIELD_DIMS)
#undef HNS_FIELD_DIMS
  throw std::invalid_argument("no batch field is called " + std::string(name));
}

}  // namespace hns::batch
