#include "xgauge/report/plot.h"

#include "xgauge/core/error.h"

#include "image/test_folder.h"

#include <gtest/gtest.h>

// Static, so that this copy does not clash with the one in preview_test.cpp.
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#include <stb_image.h>

#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace xgauge {
namespace {

// Decoded pixels, `channels` bytes each.
struct Decoded {
  std::unique_ptr<unsigned char, decltype(&stbi_image_free)> pixels{nullptr, &stbi_image_free};
  int width = 0;
  int height = 0;
  int channels = 0;
  Rgb8 at(int x, int y) const {
    const unsigned char* p = pixels.get() + (static_cast<size_t>(y) * static_cast<size_t>(width) +
                                             static_cast<size_t>(x)) *
                                                static_cast<size_t>(channels);
    return {p[0], p[1], p[2]};
  }
};

Decoded decodePng(const std::filesystem::path& path) {
  Decoded decoded;
  decoded.pixels.reset(
      stbi_load(path.c_str(), &decoded.width, &decoded.height, &decoded.channels, 0));
  EXPECT_NE(decoded.pixels, nullptr) << stbi_failure_reason();
  return decoded;
}

struct Pixel {
  int x = 0;
  int y = 0;
};

std::vector<Pixel> pixelsOf(const Decoded& image, Rgb8 colour) {
  std::vector<Pixel> found;
  if (!image.pixels || image.channels < 3) return found;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      if (image.at(x, y) == colour) found.push_back({x, y});
  return found;
}

// The plot area of a single-panel figure, inside its black frame: the frame's
// edges are the only black rows (columns) longer than half the figure.
struct Area {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
Area plotArea(const Decoded& image) {
  const Rgb8 black{0, 0, 0};
  Area frame{image.width, image.height, -1, -1};
  for (int y = 0; y < image.height; ++y) {
    int count = 0;
    for (int x = 0; x < image.width; ++x) count += image.at(x, y) == black;
    if (2 * count > image.width) frame = {frame.x0, std::min(frame.y0, y), frame.x1, y};
  }
  for (int x = 0; x < image.width; ++x) {
    int count = 0;
    for (int y = 0; y < image.height; ++y) count += image.at(x, y) == black;
    if (2 * count > image.height) frame = {std::min(frame.x0, x), frame.y0, x, frame.y1};
  }
  return {frame.x0 + 1, frame.y0 + 1, frame.x1 - 1, frame.y1 - 1};
}

constexpr Rgb8 kRed{255, 0, 0};
constexpr Rgb8 kBlue{0, 0, 255};
constexpr Rgb8 kGreen{0, 160, 0};

PlotSeries diagonal(int points, PlotSeries::Style style, Rgb8 colour) {
  PlotSeries series;
  for (int i = 0; i < points; ++i) {
    series.x.push_back(i / (points - 1.0));
    series.y.push_back(i / (points - 1.0));
  }
  series.style = style;
  series.colour = colour;
  return series;
}

PlotFigure onePanel(PlotSeries series) {
  PlotFigure figure;
  figure.width = 640;
  figure.height = 480;
  figure.x_label = "position / mm";
  figure.panels.resize(1);
  figure.panels[0].title = "Line";
  figure.panels[0].y_label = "value";
  figure.panels[0].series.push_back(std::move(series));
  return figure;
}

TEST(PlotPng, RequestedSizeAndRgb) {
  TestFolder folder;
  PlotFigure figure = onePanel(diagonal(11, PlotSeries::Style::kLine, kRed));
  figure.width = 333;
  figure.height = 257;
  writePlotPng(folder / "plot.png", figure);
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"plot.png"});
  const Decoded image = decodePng(folder / "plot.png");
  EXPECT_EQ(image.width, 333);
  EXPECT_EQ(image.height, 257);
  EXPECT_EQ(image.channels, 3);
}

TEST(PlotPng, LineGoesUpToTheRight) {
  TestFolder folder;
  PlotFigure figure = onePanel(diagonal(11, PlotSeries::Style::kLine, kRed));
  figure.panels[0].y_min = 0.0;
  figure.panels[0].y_max = 1.0;
  writePlotPng(folder / "plot.png", figure);
  const Decoded image = decodePng(folder / "plot.png");
  const Area area = plotArea(image);
  const int width = area.x1 - area.x0 + 1;
  const int height = area.y1 - area.y0 + 1;
  ASSERT_GT(width, image.width / 2);
  ASSERT_GT(height, image.height / 2);

  const std::vector<Pixel> red = pixelsOf(image, kRed);
  ASSERT_FALSE(red.empty());
  // A connected 2 px wide line, not just the 11 points: about twice the
  // diagonal's length in pixels.
  EXPECT_GT(static_cast<double>(red.size()), std::hypot(width, height));
  double sum_x = 0.0, sum_y = 0.0;
  for (const Pixel& p : red) {
    sum_x += p.x;
    sum_y += p.y;
    EXPECT_TRUE(p.x >= area.x0 && p.x <= area.x1 && p.y >= area.y0 && p.y <= area.y1)
        << "red outside the plot area at " << p.x << ", " << p.y;
  }
  EXPECT_NEAR(sum_x / static_cast<double>(red.size()), (area.x0 + area.x1) / 2.0, 0.05 * width);
  EXPECT_NEAR(sum_y / static_cast<double>(red.size()), (area.y0 + area.y1) / 2.0, 0.05 * height);

  // Counts red pixels within 10 % of the plot size from a corner.
  const auto redNear = [&](bool left, bool top) {
    int count = 0;
    for (const Pixel& p : red) {
      const bool near_x = left ? p.x - area.x0 < width / 10 : area.x1 - p.x < width / 10;
      const bool near_y = top ? p.y - area.y0 < height / 10 : area.y1 - p.y < height / 10;
      count += near_x && near_y;
    }
    return count;
  };
  EXPECT_GT(redNear(true, false), 0) << "nothing near the lower left";
  EXPECT_GT(redNear(false, true), 0) << "nothing near the upper right";
  EXPECT_EQ(redNear(true, true), 0) << "the line goes down to the right";
  EXPECT_EQ(redNear(false, false), 0) << "the line goes down to the right";
}

TEST(PlotPng, PanelsStackTopToBottom) {
  TestFolder folder;
  PlotFigure figure;
  figure.width = 500;
  figure.height = 600;
  figure.x_label = "x";
  figure.panels.resize(2);
  figure.panels[0].title = "first";
  figure.panels[0].series.push_back(diagonal(21, PlotSeries::Style::kPoints, kBlue));
  figure.panels[0].series.back().label = "blue points";
  figure.panels[1].title = "second";
  figure.panels[1].zero_line = true;
  figure.panels[1].height_weight = 0.5;
  figure.panels[1].series.push_back(diagonal(21, PlotSeries::Style::kPoints, kGreen));
  figure.panels[1].series.back().label = "green points";
  // Non-finite points are skipped, not an error.
  figure.panels[1].series.back().y[3] = std::numeric_limits<double>::quiet_NaN();
  writePlotPng(folder / "plot.png", figure);
  const Decoded image = decodePng(folder / "plot.png");

  const std::vector<Pixel> blue = pixelsOf(image, kBlue);
  const std::vector<Pixel> green = pixelsOf(image, kGreen);
  // 21 squares of 3 x 3 px, a few maybe overlapping, plus the legend's.
  EXPECT_GE(blue.size(), 100u);
  EXPECT_GE(green.size(), 100u);
  ASSERT_FALSE(blue.empty());
  ASSERT_FALSE(green.empty());
  int lowest_blue = 0;
  for (const Pixel& p : blue) lowest_blue = std::max(lowest_blue, p.y);
  int highest_green = image.height;
  for (const Pixel& p : green) highest_green = std::min(highest_green, p.y);
  EXPECT_LT(lowest_blue, highest_green);
}

TEST(PlotPng, ErrorsLeaveNoFile) {
  TestFolder folder;
  const auto path = folder / "plot.png";
  const auto expectError = [&](const PlotFigure& figure, const std::string& what) {
    try {
      writePlotPng(path, figure);
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_EQ(e.where().file, path.string()) << what;
    }
    EXPECT_FALSE(std::filesystem::exists(path)) << what;
  };

  const PlotFigure good = onePanel(diagonal(5, PlotSeries::Style::kLine, kRed));
  {
    PlotFigure figure = good;
    figure.panels.clear();
    expectError(figure, "no panels");
  }
  {
    PlotFigure figure = good;
    figure.panels[0].series[0].y.pop_back();
    expectError(figure, "x/y size mismatch");
  }
  {
    PlotFigure figure = good;
    for (double& y : figure.panels[0].series[0].y) y = std::numeric_limits<double>::quiet_NaN();
    expectError(figure, "all-NaN series");
  }
  {
    PlotFigure figure = good;
    figure.panels.push_back(PlotPanel{});  // a panel without series
    expectError(figure, "empty panel");
  }
  {
    PlotFigure figure = good;
    figure.width = 10;
    expectError(figure, "width 10");
  }
  {
    PlotFigure figure = good;
    figure.height = 8001;
    expectError(figure, "height 8001");
  }
  {
    PlotFigure figure = good;
    figure.panels[0].height_weight = 0.0;
    expectError(figure, "height_weight 0");
  }
  EXPECT_TRUE(folder.entries().empty());
  EXPECT_THROW(writePlotPng(folder / "missing" / "plot.png", good), Error);
  EXPECT_TRUE(folder.entries().empty());
}

}  // namespace
}  // namespace xgauge
