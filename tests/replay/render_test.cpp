// Top-down pictures and animated GIFs of recorded episodes (replay/render.hpp).
#include "replay/render.hpp"

#include <gd.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hns::replay {
namespace {

// One hider at (4, 1) and one cube (0.5 m) at (2, 4), turned 0.3 rad, in a 6 x 6 m arena without walls.
TrajectoryEpisode staged(int frames, uint8_t lock = kUnlocked) {
  TrajectoryEpisode ep;
  ep.scene = "empty";
  ep.layout = "empty";
  ep.horizon = frames - 1;
  ep.num_hiders = 1;
  ep.num_boxes = 1;
  ep.outer_walls = false;
  ep.box_sizes = {{0.5, 0.5, 0.5}};
  ep.resize(frames);
  for (int f = 0; f < frames; ++f) {
    ep.agent_pose[size_t(f) * 4 + 0] = 4.0f;
    ep.agent_pose[size_t(f) * 4 + 1] = 1.0f;
    ep.agent_pose[size_t(f) * 4 + 2] = 0.15f;
    ep.box_pose[size_t(f) * 4 + 0] = 2.0f;
    ep.box_pose[size_t(f) * 4 + 1] = 4.0f;
    ep.box_pose[size_t(f) * 4 + 2] = 0.25f;
    ep.box_pose[size_t(f) * 4 + 3] = 0.3f;
    ep.object_lock[size_t(f)] = lock;
  }
  return ep;
}

std::array<int, 3> pixel(const RgbImage& im, const TrajectoryEpisode& ep, double x, double y) {
  int c = 0, r = 0;
  world_to_pixel(episode_view(ep), x, y, im.width, c, r);
  EXPECT_TRUE(c >= 0 && c < im.width && r >= 0 && r < im.height) << x << ", " << y;
  const uint8_t* p = &im.rgb[(size_t(r) * im.width + c) * 3];
  return {p[0], p[1], p[2]};
}

TEST(Render, ABoxIsDrawnWhereItsPoseSays) {
  const TrajectoryEpisode ep = staged(1);
  const RgbImage im = render_frame(ep, 0, 256);
  ASSERT_EQ(im.width, 256);
  ASSERT_EQ(im.rgb.size(), size_t(256 * 256 * 3));
  const std::array<int, 3> box{176, 122, 66}, floor{236, 236, 230}, hider{66, 235, 244};
  EXPECT_EQ(pixel(im, ep, 2.0, 4.0), box) << "the cube's centre";
  // Inside the turned cube near a corner, and just outside it beyond a face.
  const double c = std::cos(0.3), s = std::sin(0.3);
  EXPECT_EQ(pixel(im, ep, 2.0 + c * 0.2 - s * 0.2, 4.0 + s * 0.2 + c * 0.2), box);
  EXPECT_EQ(pixel(im, ep, 2.0 + c * 0.35, 4.0 + s * 0.35), floor);
  EXPECT_EQ(pixel(im, ep, 4.0, 1.0), hider) << "the hider's centre";
  EXPECT_EQ(pixel(im, ep, 3.0, 3.0), floor);

  const TrajectoryEpisode locked = staged(1, kLockedByHiders);
  EXPECT_EQ(pixel(render_frame(locked, 0, 256), locked, 2.0, 4.0), (std::array<int, 3>{86, 120, 170}))
      << "a box the hiders locked";
  EXPECT_THROW(render_frame(ep, 1, 256), std::invalid_argument);
  EXPECT_THROW(render_frame(ep, 0, 10), std::invalid_argument);
}

// The logical screen size and the number of pictures of a GIF, by walking its blocks.
void gif_shape(const std::string& g, int& width, int& height, int& pictures) {
  ASSERT_EQ(g.substr(0, 6), "GIF89a");
  auto u8 = [&](size_t i) { return static_cast<uint8_t>(g.at(i)); };
  width = u8(6) | u8(7) << 8;
  height = u8(8) | u8(9) << 8;
  size_t i = 13;
  if (u8(10) & 0x80) i += 3u << ((u8(10) & 7) + 1);  // global colour table
  auto skip_sub_blocks = [&] {
    while (u8(i) != 0) i += u8(i) + 1;
    ++i;
  };
  pictures = 0;
  while (u8(i) != 0x3B) {
    if (u8(i) == 0x21) {  // extension: label, then sub-blocks
      i += 2;
      skip_sub_blocks();
    } else {
      ASSERT_EQ(u8(i), 0x2C) << "block at byte " << i;
      ++pictures;
      const uint8_t flags = u8(i + 9);
      i += 10;
      if (flags & 0x80) i += 3u << ((flags & 7) + 1);  // local colour table
      ++i;                                             // LZW minimum code size
      skip_sub_blocks();
    }
  }
}

TEST(Render, AGifHoldsOnePicturePerDrawnFrameAtTheAskedSize) {
  const TrajectoryEpisode a = staged(5), b = staged(3);
  int frames = 0, width = 0, height = 0, pictures = 0;
  GifOptions o;
  o.size = 200;
  std::string gif = encode_gif({&a, &b}, o, &frames);
  gif_shape(gif, width, height, pictures);
  EXPECT_EQ(frames, 8);
  EXPECT_EQ(pictures, 8);
  EXPECT_EQ(width, 200);
  EXPECT_EQ(height, 200);
  // Every second frame, and each episode's last: 0, 2, 4 and 0, 2.
  o.every = 2;
  gif = encode_gif({&a, &b}, o, &frames);
  gif_shape(gif, width, height, pictures);
  EXPECT_EQ(frames, 5);
  EXPECT_EQ(pictures, 5);
  // libgd reads its first picture back, with the cube where it belongs.
  gdImagePtr im = gdImageCreateFromGifPtr(static_cast<int>(gif.size()), gif.data());
  ASSERT_NE(im, nullptr);
  EXPECT_EQ(gdImageSX(im), 200);
  int c = 0, r = 0;
  world_to_pixel(episode_view(a), 2.0, 4.0, 200, c, r);
  const int px = gdImageGetPixel(im, c, r);
  EXPECT_EQ(gdImageRed(im, px), 176);
  EXPECT_EQ(gdImageGreen(im, px), 122);
  gdImageDestroy(im);
  EXPECT_THROW(encode_gif({}, o, nullptr), std::invalid_argument);
}

}  // namespace
}  // namespace hns::replay
