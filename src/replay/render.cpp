#include "replay/render.hpp"

#include <gd.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace hns::replay {
namespace {

constexpr double kArenaMin = -0.2, kArenaMax = 6.2;  // m, both axes: the arena and its outer walls
constexpr double kAgentRadius = 0.15, kArmRadius = 0.05;
constexpr double kArm[2][2] = {{-0.13, -0.075}, {0.13, -0.075}};  // arm centres in the agent's frame (m)
constexpr double kConeHalf = 67.5 * M_PI / 180, kConeLength = 0.8;
constexpr double kRampHalf = 0.25;

struct ImageDeleter {
  void operator()(gdImagePtr im) const { gdImageDestroy(im); }
};
using Image = std::unique_ptr<gdImage, ImageDeleter>;

// The palette: the same indices in every frame, so a GIF needs one global colour map.
struct Palette {
  int outside, floor, floor_prep, wall, box, box_hiders, box_seekers, ramp, ramp_edge, hider, seeker, outline,
      cone, food, site, bar;
  explicit Palette(gdImagePtr im) {
    outside = gdImageColorAllocate(im, 214, 214, 208);  // the first colour is the background
    floor = gdImageColorAllocate(im, 236, 236, 230);
    floor_prep = gdImageColorAllocate(im, 246, 238, 206);
    wall = gdImageColorAllocate(im, 70, 74, 80);
    box = gdImageColorAllocate(im, 176, 122, 66);
    box_hiders = gdImageColorAllocate(im, 86, 120, 170);
    box_seekers = gdImageColorAllocate(im, 170, 70, 60);
    ramp = gdImageColorAllocate(im, 150, 160, 90);
    ramp_edge = gdImageColorAllocate(im, 70, 80, 30);
    hider = gdImageColorAllocate(im, 66, 235, 244);
    seeker = gdImageColorAllocate(im, 235, 70, 70);
    outline = gdImageColorAllocate(im, 20, 20, 20);
    cone = gdImageColorAllocate(im, 130, 130, 130);
    food = gdImageColorAllocate(im, 240, 200, 20);
    site = gdImageColorAllocate(im, 120, 120, 200);
    bar = gdImageColorAllocate(im, 240, 190, 30);
  }
};

struct View {
  ViewBox box;
  int size;
  double scale() const { return size / box.span; }
  gdPoint at(double x, double y) const {
    int c, r;
    world_to_pixel(box, x, y, size, c, r);
    return gdPoint{c, r};
  }
  int len(double m) const { return std::max(1, static_cast<int>(std::lround(m * scale()))); }
};

// A rectangle of half extents (hx, hy) centred at (cx, cy), turned by yaw.
void rotated_rect(gdImagePtr im, const View& v, double cx, double cy, double hx, double hy, double yaw,
                  int fill, int edge) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  gdPoint p[4];
  const double corners[4][2] = {{-hx, -hy}, {hx, -hy}, {hx, hy}, {-hx, hy}};
  for (int k = 0; k < 4; ++k) {
    p[k] = v.at(cx + c * corners[k][0] - s * corners[k][1], cy + s * corners[k][0] + c * corners[k][1]);
  }
  gdImageFilledPolygon(im, p, 4, fill);
  gdImagePolygon(im, p, 4, edge);
}

void disc(gdImagePtr im, const View& v, double x, double y, double r, int fill, int edge) {
  const gdPoint p = v.at(x, y);
  const int d = 2 * v.len(r);
  gdImageFilledEllipse(im, p.x, p.y, d, d, fill);
  gdImageArc(im, p.x, p.y, d, d, 0, 360, edge);
}

int lock_colour(const Palette& pal, uint8_t lock, int unlocked) {
  return lock == kLockedByHiders ? pal.box_hiders : lock == kLockedBySeekers ? pal.box_seekers : unlocked;
}

void draw(gdImagePtr im, const Palette& pal, const TrajectoryEpisode& ep, const ViewBox& box, int f,
          int size) {
  const View v{box, size};
  const bool prep = ep.prep[size_t(f)] != 0;
  // Around the 6 x 6 m arena (where the full game's open floor goes on) a little darker.
  gdImageFilledRectangle(im, 0, 0, size - 1, size - 1, pal.outside);
  const gdPoint lo = v.at(0, 0), hi = v.at(6, 6);
  gdImageFilledRectangle(im, lo.x, hi.y, hi.x, lo.y, prep ? pal.floor_prep : pal.floor);
  for (const auto& s : ep.sites)
    rotated_rect(im, v, s[0], s[1], s[2] / 2, s[2] / 2, 0, prep ? pal.floor_prep : pal.floor, pal.site);
  for (const auto& w : ep.walls) rotated_rect(im, v, w[0], w[1], w[3], w[4], 0, pal.wall, pal.wall);
  for (const auto& c : ep.cylinders) disc(im, v, c[0], c[1], c[2], pal.wall, pal.wall);
  const int nb = ep.num_boxes, nr = ep.num_ramps, na = ep.num_agents(), no = ep.num_objects();
  for (int b = 0; b < nb; ++b) {
    const float* p = &ep.box_pose[(size_t(f) * nb + b) * 4];
    const auto& sz = ep.box_sizes[size_t(b)];
    rotated_rect(im, v, p[0], p[1], sz[0] / 2, sz[1] / 2, p[3],
                 lock_colour(pal, ep.object_lock[size_t(f) * no + b], pal.box), pal.outline);
  }
  for (int r = 0; r < nr; ++r) {
    const float* p = &ep.ramp_pose[(size_t(f) * nr + r) * 4];
    rotated_rect(im, v, p[0], p[1], kRampHalf, kRampHalf, p[3],
                 lock_colour(pal, ep.object_lock[size_t(f) * no + nb + r], pal.ramp), pal.outline);
    // The high edge: the back face, at y = -0.25 in the ramp's frame.
    const double c = std::cos(p[3]), s = std::sin(p[3]);
    const gdPoint a = v.at(p[0] - c * kRampHalf + s * kRampHalf, p[1] - s * kRampHalf - c * kRampHalf);
    const gdPoint b = v.at(p[0] + c * kRampHalf + s * kRampHalf, p[1] + s * kRampHalf - c * kRampHalf);
    gdImageSetThickness(im, std::max(2, size / 160));
    gdImageLine(im, a.x, a.y, b.x, b.y, pal.ramp_edge);
    gdImageSetThickness(im, 1);
  }
  for (int k = 0; k < ep.num_food; ++k) {
    const float* p = &ep.food[(size_t(f) * ep.num_food + k) * 4];
    if (p[3] > 0) disc(im, v, p[0], p[1], 0.08, pal.food, pal.outline);
  }
  for (int a = 0; a < na; ++a) {
    const float* p = &ep.agent_pose[(size_t(f) * na + a) * 4];
    const double c = std::cos(p[3]), s = std::sin(p[3]);
    // The front is the agent's -y side: direction (sin yaw, -cos yaw).
    const double front = std::atan2(-c, s);
    const gdPoint o = v.at(p[0], p[1]);
    for (const double side : {-kConeHalf, kConeHalf}) {
      const gdPoint e =
          v.at(p[0] + kConeLength * std::cos(front + side), p[1] + kConeLength * std::sin(front + side));
      gdImageLine(im, o.x, o.y, e.x, e.y, pal.cone);
    }
    const int colour = a < ep.num_hiders ? pal.hider : pal.seeker;
    for (const auto& arm : kArm) {
      disc(im, v, p[0] + c * arm[0] - s * arm[1], p[1] + s * arm[0] + c * arm[1], kArmRadius, colour,
           pal.outline);
    }
    disc(im, v, p[0], p[1], kAgentRadius, colour, pal.outline);
  }
  if (prep) gdImageFilledRectangle(im, 0, 0, size - 1, std::max(2, size / 40), pal.bar);
}

void check_size(int size) {
  if (size < 64 || size > 4096) {
    throw std::invalid_argument("picture size " + std::to_string(size) + " px: must be in [64, 4096]");
  }
}

}  // namespace

ViewBox episode_view(const TrajectoryEpisode& ep) {
  double lo[2] = {kArenaMin, kArenaMin}, hi[2] = {kArenaMax, kArenaMax};
  auto cover = [&](const std::vector<float>& pose, double margin) {
    for (size_t i = 0; i + 3 < pose.size(); i += 4) {
      for (int k = 0; k < 2; ++k) {
        if (!std::isfinite(pose[i + k])) continue;
        lo[k] = std::min(lo[k], pose[i + k] - margin);
        hi[k] = std::max(hi[k], pose[i + k] + margin);
      }
    }
  };
  cover(ep.agent_pose, 0.3);
  cover(ep.ramp_pose, 0.4);
  for (int b = 0; b < ep.num_boxes; ++b) {
    const double half = 0.5 * std::hypot(ep.box_sizes[size_t(b)][0], ep.box_sizes[size_t(b)][1]) + 0.05;
    for (int f = 0; f < ep.frames; ++f) {
      const float* p = &ep.box_pose[(size_t(f) * ep.num_boxes + b) * 4];
      for (int k = 0; k < 2; ++k) {
        if (!std::isfinite(p[k])) continue;
        lo[k] = std::min(lo[k], p[k] - half), hi[k] = std::max(hi[k], p[k] + half);
      }
    }
  }
  // Bodies far off (a trajectory's poses are only checked to be finite) make the view at most 1 km wide.
  for (int k = 0; k < 2; ++k) lo[k] = std::max(lo[k], -500.0), hi[k] = std::min(hi[k], 500.0);
  const double span = std::max(hi[0] - lo[0], hi[1] - lo[1]);
  // Centred on the covered rectangle, square.
  return ViewBox{0.5 * (lo[0] + hi[0]) - 0.5 * span, 0.5 * (lo[1] + hi[1]) - 0.5 * span, span};
}

void world_to_pixel(const ViewBox& view, double x, double y, int size, int& column, int& row) {
  const double scale = size / view.span;
  column = static_cast<int>(std::floor((x - view.x0) * scale));
  row = static_cast<int>(std::floor((view.y0 + view.span - y) * scale));
}

RgbImage render_frame(const TrajectoryEpisode& episode, int frame, int size) {
  check_size(size);
  if (frame < 0 || frame >= episode.frames) {
    throw std::invalid_argument("frame " + std::to_string(frame) + ": the episode has frames 0 to " +
                                std::to_string(episode.frames - 1));
  }
  const Image im(gdImageCreate(size, size));
  if (!im) throw std::runtime_error("out of memory for a picture");
  const Palette pal(im.get());
  draw(im.get(), pal, episode, episode_view(episode), frame, size);
  RgbImage out{size, size, std::vector<uint8_t>(size_t(size) * size * 3)};
  for (int r = 0; r < size; ++r) {
    for (int c = 0; c < size; ++c) {
      const int px = gdImageGetPixel(im.get(), c, r);
      uint8_t* o = &out.rgb[(size_t(r) * size + c) * 3];
      o[0] = uint8_t(gdImageRed(im.get(), px));
      o[1] = uint8_t(gdImageGreen(im.get(), px));
      o[2] = uint8_t(gdImageBlue(im.get(), px));
    }
  }
  return out;
}

std::string encode_gif(const std::vector<const TrajectoryEpisode*>& episodes, const GifOptions& options,
                       int* frames) {
  check_size(options.size);
  if (options.every < 1) throw std::invalid_argument("every: must be at least 1");
  if (!(options.speed > 0 && options.speed <= 100)) throw std::invalid_argument("speed: must be in (0, 100]");
  if (episodes.empty()) throw std::invalid_argument("no episodes to draw");
  const int size = options.size;
  const Image first(gdImageCreate(size, size));
  if (!first) throw std::runtime_error("out of memory for a picture");
  const Palette pal(first.get());  // the colours of `first` become the GIF's global colour map
  std::string gif;
  int n = 0;
  // libgd hands each piece back as a buffer of n bytes to free (n is set by the call, so read it after).
  auto append = [&gif, &n](void* bytes) {
    if (bytes == nullptr) throw std::runtime_error("libgd could not encode a GIF picture");
    gif.append(static_cast<const char*>(bytes), size_t(n));
    gdFree(bytes);
  };
  append(gdImageGifAnimBeginPtr(first.get(), &n, 1, 0));
  int count = 0;
  for (const TrajectoryEpisode* ep : episodes) {
    const ViewBox view = episode_view(*ep);
    // Delay in hundredths of a second between drawn frames, at most 65535 / 4 (a 16-bit field; the last
    // frame holds four times as long).
    const int delay = static_cast<int>(
        std::clamp(std::lround(100 * ep->step_time * options.every / options.speed), 2L, 16383L));
    for (int f = 0; f < ep->frames; ++f) {
      if (f % options.every != 0 && f != ep->frames - 1) continue;
      const Image im(gdImageCreate(size, size));
      if (!im) throw std::runtime_error("out of memory for a picture");
      const Palette same(im.get());  // allocated in the same order: the global colour map's indices
      draw(im.get(), same, *ep, view, f, size);
      append(gdImageGifAnimAddPtr(im.get(), &n, 0, 0, 0, f == ep->frames - 1 ? 4 * delay : delay,
                                  gdDisposalNone, nullptr));
      ++count;
    }
  }
  append(gdImageGifAnimEndPtr(&n));
  if (frames != nullptr) *frames = count;
  return gif;
}

}  // namespace hns::replay
