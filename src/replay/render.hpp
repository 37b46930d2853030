// Top-down pictures of recorded episodes: one frame as RGB pixels, or episodes as an animated GIF.
//
// Drawn with libgd (Debian's libgd-dev): it draws filled polygons and circles and writes animated GIFs
// itself, so one small, long-kept C library does both the drawing and the encoding (no video stack).
// The view is the arena, x and y in [-0.2, 6.2] m, grown where an episode's bodies leave it; +y up. Walls
// dark grey, boxes brown (blue-grey where hiders locked them, red-brown where seekers did), ramps olive with
// a dark line on the high back edge, hiders cyan and seekers red with their two arms and a thin vision cone
// (135 degrees, 0.8 m), food yellow, blueprint sites as outlines. During the preparation phase the floor is
// tinted and a yellow bar runs along the top.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "replay/trajectory.hpp"

namespace hns::replay {

struct RgbImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // row-major, top row first, 3 bytes per pixel
};

// Frame `frame` of `episode` as a size x size picture. Throws std::invalid_argument for a frame outside the
// episode or a size outside [64, 4096].
RgbImage render_frame(const TrajectoryEpisode& episode, int frame, int size);

// The square of the world a picture shows (m): lower-left corner and side.
struct ViewBox {
  double x0, y0, span;
};
// An episode's view: the arena (x, y in [-0.2, 6.2] m) grown to hold every agent, box and ramp of every
// frame (the full game has no outer walls), centred, square. The same for all of the episode's pictures.
ViewBox episode_view(const TrajectoryEpisode& episode);
// The pixel (column, row) a world point (m) falls on in a size x size picture of `view` (may lie outside).
void world_to_pixel(const ViewBox& view, double x, double y, int size, int& column, int& row);

struct GifOptions {
  int size = 320;    // pixels per side, [64, 4096]
  int every = 1;     // draw every k-th frame (and always an episode's last)
  double speed = 1;  // playback speed relative to real time (an env step is step_time seconds)
};

// The episodes one after another as an animated GIF (looping), returned as bytes; `frames`, if given,
// receives how many pictures it holds. Throws std::invalid_argument for bad options or no episodes.
std::string encode_gif(const std::vector<const TrajectoryEpisode*>& episodes, const GifOptions& options,
                       int* frames = nullptr);

}  // namespace hns::replay
