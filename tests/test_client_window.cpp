// The client as a program: a real window under Xvfb (screenshot with xwd equals the headless
// image of the same view; a resize mid-run stays free of crashes and validation errors), and
// a corrupt baked file (clear error, ambient-lit image). Needs Xvfb and xwd (x11-apps) for
// the window tests; they skip with a message without them.
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "common/image.h"
#include "common/scene.h"
#include "protocol/baked_file.h"
#include "test_client_support.h"

extern char** environ;

namespace pc::client::test {
namespace {

namespace fs = std::filesystem;

const std::string kClient = std::string(PC_BUILD_DIR) + "/bin/probecast-client";

fs::path workDir(const std::string& name) {
  const fs::path dir = fs::path(PC_BUILD_DIR) / "test-client-window" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

bool onPath(const std::string& program) {
  return std::system(("command -v " + program + " >/dev/null 2>&1").c_str()) == 0;
}

// Starts `argv` with extra environment entries; returns the pid (or -1).
pid_t spawn(const std::vector<std::string>& argv, const std::vector<std::string>& env = {}) {
  std::vector<std::string> envStrings;
  for (char** e = environ; *e; ++e) envStrings.emplace_back(*e);
  envStrings.insert(envStrings.end(), env.begin(), env.end());
  std::vector<char*> args, envp;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  for (const std::string& e : envStrings) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, argv[0].c_str(), nullptr, nullptr, args.data(), envp.data()) != 0)
    return -1;
  return pid;
}

int waitExit(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// An Xvfb server on a free display for the test's lifetime.
class Xvfb {
 public:
  bool start() {
    for (int d = 70 + int(getpid() % 100); d < 300; ++d) {
      if (fs::exists("/tmp/.X11-unix/X" + std::to_string(d)) ||
          fs::exists("/tmp/.X" + std::to_string(d) + "-lock"))
        continue;
      // Appended, not ":" + string: GCC 12 warns (-Wrestrict, a false positive) on that form.
      display_ = ":";
      display_ += std::to_string(d);
      pid_ = spawn({"Xvfb", display_, "-screen", "0", "640x480x24", "-nolisten", "tcp"});
      if (pid_ < 0) return false;
      for (int i = 0; i < 100; ++i) {
        if (fs::exists("/tmp/.X11-unix/X" + std::to_string(d))) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      return false;
    }
    return false;
  }
  ~Xvfb() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitExit(pid_);
    }
  }
  const std::string& display() const { return display_; }

 private:
  pid_t pid_ = -1;
  std::string display_;
};

// XWD files (X Window Dump, as xwd writes them): a header of 25 big-endian 32-bit fields,
// the window name, the colormap entries, then the pixels as the X server stores them. Only
// the TrueColor 24/32-bit formats Xvfb uses are read.
Result<Image8> readXwd(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  if (bytes.size() < 100) return Error{path.string() + ": too short for an XWD header"};
  auto field = [&](int i) {
    const unsigned char* p = &bytes[std::size_t(i) * 4];
    return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | p[3];
  };
  const std::uint32_t headerSize = field(0), width = field(4), height = field(5);
  const std::uint32_t byteOrder = field(7), bitsPerPixel = field(11), bytesPerLine = field(12);
  const std::uint32_t redMask = field(14), greenMask = field(15), blueMask = field(16);
  const std::uint32_t colormapEntries = field(19);
  if (bitsPerPixel != 32) return Error{"XWD: only 32 bits per pixel supported"};
  const std::size_t data = std::size_t(headerSize) + std::size_t(colormapEntries) * 12;
  if (bytes.size() < data + std::size_t(bytesPerLine) * height)
    return Error{path.string() + ": truncated XWD pixels"};
  auto shiftOf = [](std::uint32_t mask) {
    int s = 0;
    while (mask && !(mask & 1u)) {
      mask >>= 1;
      ++s;
    }
    return s;
  };
  Image8 image;
  image.width = int(width);
  image.height = int(height);
  image.rgb.resize(std::size_t(width) * height * 3);
  for (std::uint32_t y = 0; y < height; ++y) {
    for (std::uint32_t x = 0; x < width; ++x) {
      const unsigned char* p = &bytes[data + std::size_t(y) * bytesPerLine + x * 4];
      const std::uint32_t v = byteOrder == 0
                                  ? (std::uint32_t(p[3]) << 24 | std::uint32_t(p[2]) << 16 |
                                     std::uint32_t(p[1]) << 8 | p[0])
                                  : (std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 |
                                     std::uint32_t(p[2]) << 8 | p[3]);
      unsigned char* out = &image.rgb[(std::size_t(y) * width + x) * 3];
      out[0] = static_cast<unsigned char>((v & redMask) >> shiftOf(redMask));
      out[1] = static_cast<unsigned char>((v & greenMask) >> shiftOf(greenMask));
      out[2] = static_cast<unsigned char>((v & blueMask) >> shiftOf(blueMask));
    }
  }
  return image;
}

// A baked field of the built-in room, written once per test binary run.
fs::path builtinProbes() {
  static const fs::path path = [] {
    const fs::path p = fs::path(PC_BUILD_DIR) / "test-client-window" / "builtin.probes";
    fs::create_directories(p.parent_path());
    const Scene scene = builtinScene();
    const Field field = bakeQuickly(scene, 8);
    EXPECT_TRUE(writeBakedField(p, field).ok());
    return p;
  }();
  return path;
}

bool waitForFile(const fs::path& p, pid_t pid, int seconds) {
  for (int i = 0; i < seconds * 20; ++i) {
    if (fs::exists(p)) return true;
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return false;  // exited early
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

// Columns [x0, x0 + width) of `image`.
Image8 columns(const Image8& image, int x0, int width) {
  Image8 out;
  out.width = width;
  out.height = image.height;
  out.rgb.resize(std::size_t(width) * image.height * 3);
  for (int y = 0; y < image.height; ++y) {
    std::memcpy(&out.rgb[std::size_t(y) * width * 3],
                &image.rgb[(std::size_t(y) * image.width + x0) * 3], std::size_t(width) * 3);
  }
  return out;
}

// A screenshot of the window against the headless image of the same view; stereo windows
// show both eyes side by side, each half the window's width. `extra`: flags both runs take.
void screenshotMatchesHeadless(bool stereo, const std::vector<std::string>& extra = {},
                               const std::string& name = "") {
  if (!onPath("Xvfb") || !onPath("xwd")) GTEST_SKIP() << "needs Xvfb and xwd (xvfb, x11-apps)";
  Xvfb x;
  ASSERT_TRUE(x.start()) << "Xvfb did not start";
  const fs::path dir = workDir(!name.empty() ? name : stereo ? "screenshot-stereo" : "screenshot");
  const std::string probes = builtinProbes().string();
  const int eyeWidth = 160;
  std::vector<std::string> common = {"--scene",  "builtin", "--probes", probes,
                                     "--height", "120",     "--dt",     "0"};
  if (stereo) common.push_back("--stereo");
  common.insert(common.end(), extra.begin(), extra.end());
  std::vector<std::string> windowed = {
      kClient,        "--window",
      "--frames",     "16",
      "--no-overlay", "--validation",
      "--ready-file", (dir / "ready").string(),
      "--width",      std::to_string(stereo ? 2 * eyeWidth : eyeWidth)};
  windowed.insert(windowed.end(), common.begin(), common.end());
  const pid_t client = spawn(windowed, {"DISPLAY=" + x.display()});
  ASSERT_GT(client, 0);
  const bool ready = waitForFile(dir / "ready", client, 50);
  int shot = -1;
  if (ready) {
    shot = std::system(("xwd -display " + x.display() + " -name probecast -silent -out " +
                        (dir / "window.xwd").string())
                           .c_str());
  }
  EXPECT_EQ(waitExit(client), 0) << "windowed client failed (validation errors exit with 3)";
  ASSERT_TRUE(ready) << "the window never became ready";
  ASSERT_EQ(shot, 0) << "xwd failed";

  std::vector<std::string> headless = {kClient,    "--out",   dir.string(),
                                       "--no-exr", "--width", std::to_string(eyeWidth)};
  headless.insert(headless.end(), common.begin(), common.end());
  const pid_t h = spawn(headless);
  ASSERT_EQ(waitExit(h), 0);

  auto window = readXwd(dir / "window.xwd");
  ASSERT_TRUE(window.ok()) << window.error().message;
  const int eyes = stereo ? 2 : 1;
  ASSERT_EQ(window->width, eyes * eyeWidth);
  for (int eye = 0; eye < eyes; ++eye) {
    const char* suffix = stereo ? (eye == 0 ? "_left" : "_right") : "";
    auto offscreen = readPng(dir / (std::string("frame_0000") + suffix + ".png"));
    ASSERT_TRUE(offscreen.ok()) << offscreen.error().message;
    ASSERT_EQ(offscreen->width, eyeWidth);
    ASSERT_EQ(window->height, offscreen->height);
    const double db = psnr8(columns(*window, eye * eyeWidth, eyeWidth), *offscreen);
    std::printf("window screenshot%s vs headless image: %.2f dB\n", suffix, db);
    EXPECT_GE(db, 40.0);
  }
}

TEST(ClientWindow, ScreenshotMatchesHeadlessImage) { screenshotMatchesHeadless(false); }

TEST(ClientWindow, StereoScreenshotShowsBothEyesSideBySide) { screenshotMatchesHeadless(true); }

// The probe view's flags reach the window as they reach headless runs (the view itself is
// checked against a golden image in test_client_probe_view).
TEST(ClientWindow, ProbeViewScreenshotMatchesHeadlessImage) {
  screenshotMatchesHeadless(false, {"--probe-view", "state", "--probe-cascade", "1"},
                            "screenshot-probe-view");
}

TEST(ClientWindow, ResizeDuringTheRunKeepsValidationQuiet) {
  if (!onPath("Xvfb")) GTEST_SKIP() << "needs Xvfb (xvfb)";
  Xvfb x;
  ASSERT_TRUE(x.start()) << "Xvfb did not start";
  const pid_t client = spawn(
      {kClient, "--window", "--scene", "builtin", "--probes", builtinProbes().string(), "--width",
       "160", "--height", "120", "--frames", "8", "--validation", "--test-resize", "224x136"},
      {"DISPLAY=" + x.display()});
  ASSERT_GT(client, 0);
  EXPECT_EQ(waitExit(client), 0) << "crash, error or validation errors (exit 3) around a resize";
}

// A --probes file that cannot be used ends the run with exit code 1 and the reader's message,
// before any frame: an image lit by the ambient term alone would pass for one lit by the field.
TEST(ClientFallback, CorruptBakedFileEndsTheRunWithExitCode1) {
  const fs::path dir = workDir("corrupt");
  {
    std::ofstream bad(dir / "bad.probes", std::ios::binary);
    bad << "this is not a probe field";
  }
  const std::string log = (dir / "log.txt").string();
  const int rc =
      std::system((kClient + " --scene builtin --width 96 --height 64 --validation --probes " +
                   (dir / "bad.probes").string() + " --out " + dir.string() + " 2> " + log)
                      .c_str());
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_EQ(WEXITSTATUS(rc), 1);
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("cannot use the baked field: baked file " + (dir / "bad.probes").string() +
                      ": not a baked field file"),
            std::string::npos)
      << text;
  EXPECT_FALSE(fs::exists(dir / "frame_0000.exr"));
}

}  // namespace
}  // namespace pc::client::test
