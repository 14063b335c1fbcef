#include "xgauge/report/html.h"

#include <gtest/gtest.h>

#include <regex>

namespace xgauge {
namespace {

TEST(ReportPage, EmbedsTheDataSoThatNoStringCanCloseItsScript) {
  const nlohmann::json data = {{"note", "</script><script>alert(1)</script>"}, {"x", 1.5}};
  const std::string page = reportPage(ReportKind::kMeasurement, "a <b> & c", data);
  EXPECT_EQ(page.find("alert(1)</script>"), std::string::npos);
  EXPECT_NE(page.find("\\u003c/script>\\u003cscript>alert(1)"), std::string::npos);
  EXPECT_NE(page.find("<title>a &lt;b&gt; &amp; c</title>"), std::string::npos);
  EXPECT_NE(page.find("data-report=\"measurement\""), std::string::npos);
  // The embedded JSON reads back as given.
  const std::string open = "<script type=\"application/json\" id=\"xgauge-data\">";
  const size_t begin = page.find(open) + open.size();
  std::string json = page.substr(begin, page.find("</script>", begin) - begin);
  json = std::regex_replace(json, std::regex(R"(\\u003c)"), "<");
  EXPECT_EQ(nlohmann::json::parse(json), data);
}

TEST(ReportPage, FetchesNothingAndCarriesTheChartLibraryWithItsLicence) {
  const std::string page = reportPage(ReportKind::kStudy, "t", nlohmann::json::object());
  EXPECT_NE(page.find("Content-Security-Policy"), std::string::npos);
  EXPECT_NE(page.find("default-src 'none'"), std::string::npos);
  EXPECT_NE(page.find("Permission is hereby granted"), std::string::npos);  // MIT licence
  EXPECT_NE(page.find("var uPlot"), std::string::npos);
  // No element loads anything from elsewhere.
  EXPECT_FALSE(std::regex_search(page, std::regex(R"((src|href)\s*=\s*["']?(https?:|//|file:))")));
}

TEST(PngDataUri, IsBase64OfTheBytes) {
  EXPECT_EQ(pngDataUri("abc"), "data:image/png;base64,YWJj");
  EXPECT_EQ(pngDataUri("ab"), "data:image/png;base64,YWI=");
  EXPECT_EQ(pngDataUri(""), "data:image/png;base64,");
}

TEST(Pictures, ShrinkByTheSmallestIntegerFactorThatFits) {
  const Image image(1300, 200, 0.5f);
  const nlohmann::json p = greyPicture(image, {10, 20, 1300, 200}, {0.0, 1.0}, 640);
  EXPECT_EQ(p.at("factor"), 3);  // 1300 / 3 = 434 <= 640 < 650
  EXPECT_EQ(p.at("at"), nlohmann::json({10, 20, 1300, 200}));
  EXPECT_EQ(p.at("uri").get<std::string>().rfind("data:image/png;base64,iVBORw0KGgo", 0), 0u);
  const nlohmann::json same = greyPicture(Image(640, 10, 0.5f), {0, 0, 640, 10}, {0.0, 1.0}, 640);
  EXPECT_EQ(same.at("factor"), 1);
  EXPECT_DEATH(residualPicture(image, image.rect(), 0.0, 640), "residual scale 0 is not > 0");
}

TEST(ResidualScale, IsARoundNumberAboveTheBulkSharedByEveryImage) {
  // 1000 pixels of |r| = 0.003 and 2 outliers of 0.5: the 99.5th percentile
  // ignores the outliers and 0.003 rounds up to 0.005.
  Image a(1000, 1, 0.003f), b(2, 1, 0.5f);
  for (int x = 0; x < 1000; x += 2) a(x, 0) = -0.003f;
  EXPECT_DOUBLE_EQ(residualScale({&a, &b}), 0.005);
  // The scale of the pair is that of the union: the larger one wins.
  Image c(1000, 1, 0.015f);
  EXPECT_DOUBLE_EQ(residualScale({&a, &c}), 0.02);
  EXPECT_DOUBLE_EQ(residualScale({&c, &a}), 0.02);
  Image exact(10, 1, 0.2f);
  EXPECT_DOUBLE_EQ(residualScale({&exact}), 0.2);
  Image zero(4, 4, 0.0f);
  EXPECT_DOUBLE_EQ(residualScale({&zero}), 1e-6);
}

}  // namespace
}  // namespace xgauge
