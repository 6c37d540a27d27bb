#include "wavebrdf/io.h"

#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfRgbaFile.h>
#include <gtest/gtest.h>
#include <png.h>

namespace fs = std::filesystem;
using wavebrdf::Heightfield;
using wavebrdf::RgbImage;

namespace {

// A fresh directory per test, so leftovers from one test cannot satisfy another's checks.
class IoTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        m_dir = fs::path(WAVEBRDF_TEST_TMP) / "io" / (std::string(info->name()) + "-" + std::to_string(::getpid()));
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override {
        std::error_code ignored;
        fs::remove_all(m_dir, ignored);
    }
    std::string file(const std::string& name) const { return (m_dir / name).string(); }
    std::vector<std::string> listing() const {
        std::vector<std::string> names;
        for (const auto& entry : fs::directory_iterator(m_dir)) names.push_back(entry.path().filename().string());
        return names;
    }

    fs::path m_dir;
};

// Values exactly representable in both half and float: small multiples of 1/8.
Heightfield make_field(int rows, int cols) {
    std::vector<double> values(static_cast<std::size_t>(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) values[static_cast<std::size_t>(i) * cols + j] = 0.125 * (i * 17 - j * 5) - 3.0;
    return Heightfield(rows, cols, values);
}

// Expects `call` to throw exactly `Exception` with the path somewhere in its message.
template <typename Exception, typename Call>
void expect_throw_naming(Call call, const std::string& path) {
    try {
        call();
        ADD_FAILURE() << "no exception for " << path;
    } catch (const Exception& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find(path), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << "message is not one line: " << message;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
    }
}

struct Png {
    int rows = 0;
    int cols = 0;
    std::vector<std::uint8_t> pixels;
};

Png read_png(const std::string& path, bool rgb) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (png_image_begin_read_from_file(&image, path.c_str()) == 0)
        throw std::runtime_error("cannot read " + path + ": " + image.message);
    image.format = rgb ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
    Png png;
    png.rows = static_cast<int>(image.height);
    png.cols = static_cast<int>(image.width);
    png.pixels.resize(PNG_IMAGE_SIZE(image));
    if (png_image_finish_read(&image, nullptr, png.pixels.data(), 0, nullptr) == 0)
        throw std::runtime_error("cannot decode " + path + ": " + image.message);
    return png;
}

// Writes a single float channel `channel` with the given data window (x = column, y = row).
void write_exr_channel(const std::string& path, const char* channel, int rows, int cols, int x0, int y0,
                       const std::vector<float>& data) {
    Imf::Header header(Imath::Box2i({0, 0}, {x0 + cols + 2, y0 + rows + 2}),
                       Imath::Box2i({x0, y0}, {x0 + cols - 1, y0 + rows - 1}));
    header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
    Imf::FrameBuffer frame;
    frame.insert(channel, Imf::Slice::Make(Imf::FLOAT, data.data(), header.dataWindow()));
    Imf::OutputFile out(path.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(rows);
}

TEST_F(IoTest, HeightfieldFloatExrRoundTripsNonSquare) {
    const Heightfield field = make_field(7, 13);
    const std::string path = file("field.exr");
    wavebrdf::write_heightfield_exr(path, field);
    const Heightfield back = wavebrdf::read_heightfield_exr(path, 2.5, 0.5);
    ASSERT_EQ(back.rows(), 7);
    ASSERT_EQ(back.cols(), 13);
    EXPECT_EQ(back.values(), field.values());
    EXPECT_EQ(back.texel_um(), 2.5);
    EXPECT_EQ(back.vscale(), 0.5);
    // Only the target remains: the temporary was renamed, not copied.
    EXPECT_EQ(listing(), std::vector<std::string>{"field.exr"});
}

TEST_F(IoTest, ReadsHalfExrWrittenWithRgbaApi) {
    const int rows = 5, cols = 3;
    std::vector<Imf::Rgba> pixels(rows * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            pixels[i * cols + j] = Imf::Rgba(half(0.25f * static_cast<float>(i) - 0.5f * static_cast<float>(j)),
                                             half(1.0f), half(2.0f), half(1.0f));
    const std::string path = file("half.exr");
    {
        Imf::RgbaOutputFile out(path.c_str(), cols, rows, Imf::WRITE_RGBA);
        out.setFrameBuffer(pixels.data(), 1, cols);
        out.writePixels(rows);
    }
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), rows);
    ASSERT_EQ(field.cols(), cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) EXPECT_EQ(field.value(i, j), 0.25 * i - 0.5 * j) << i << "," << j;

    const RgbImage image = wavebrdf::read_rgb_exr(path);
    ASSERT_EQ(image.rows, rows);
    ASSERT_EQ(image.cols, cols);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 0], 0.25f - 1.0f);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 1], 1.0f);
    EXPECT_EQ(image.data[(1 * cols + 2) * 3 + 2], 2.0f);
}

TEST_F(IoTest, HonoursDataWindowOffset) {
    const int rows = 4, cols = 6;
    std::vector<float> data(rows * cols);
    for (int k = 0; k < rows * cols; ++k) data[k] = static_cast<float>(k);
    const std::string path = file("offset.exr");
    write_exr_channel(path, "R", rows, cols, 3, 5, data);
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), rows);
    ASSERT_EQ(field.cols(), cols);
    EXPECT_EQ(field.value(0, 0), 0.0);
    EXPECT_EQ(field.value(2, 5), 2.0 * cols + 5);
    EXPECT_EQ(field.value(3, 1), 3.0 * cols + 1);
}

TEST_F(IoTest, AcceptsLuminanceOnlyExr) {
    const std::vector<float> data = {1.5f, -2.0f, 0.0f, 4.0f, 8.0f, -0.25f};
    const std::string path = file("y.exr");
    write_exr_channel(path, "Y", 2, 3, 0, 0, data);
    const Heightfield field = wavebrdf::read_heightfield_exr(path);
    ASSERT_EQ(field.rows(), 2);
    ASSERT_EQ(field.cols(), 3);
    EXPECT_EQ(field.value(1, 2), -0.25);
    const RgbImage image = wavebrdf::read_rgb_exr(path);
    EXPECT_EQ(image.data[(1 * 3 + 0) * 3 + 2], 4.0f);
}

TEST_F(IoTest, RgbExrRoundTripsWithAndWithoutAlpha) {
    RgbImage image{2, 3, {}};
    for (int k = 0; k < 2 * 3 * 3; ++k) image.data.push_back(0.1f * static_cast<float>(k) - 0.7f);
    for (bool alpha : {false, true}) {
        const std::string path = file(alpha ? "rgba.exr" : "rgb.exr");
        wavebrdf::write_rgb_exr(path, image, alpha);
        const RgbImage back = wavebrdf::read_rgb_exr(path);
        EXPECT_EQ(back.rows, 2);
        EXPECT_EQ(back.cols, 3);
        EXPECT_EQ(back.data, image.data);
        Imf::InputFile in(path.c_str());
        const Imf::ChannelList& channels = in.header().channels();
        EXPECT_EQ(channels.findChannel("A") != nullptr, alpha);
        ASSERT_NE(channels.findChannel("G"), nullptr);
        EXPECT_EQ(channels.findChannel("G")->type, Imf::FLOAT);
        if (alpha) {
            std::vector<float> a(6, 0.0f);
            Imf::FrameBuffer frame;
            frame.insert("A", Imf::Slice::Make(Imf::FLOAT, a.data(), in.header().dataWindow()));
            in.setFrameBuffer(frame);
            in.readPixels(0, 1);
            EXPECT_EQ(a, std::vector<float>(6, 1.0f));
        }
    }
}

TEST_F(IoTest, MissingFileThrowsNamingPath) {
    const std::string path = file("absent.exr");
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
}

TEST_F(IoTest, TextFileThrowsNamingPath) {
    const std::string path = file("notes.exr");
    std::ofstream(path) << "this is not an image\n";
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

TEST_F(IoTest, TruncatedExrThrowsNamingPath) {
    // Big and noisy enough that half the file cuts through pixel data, not just the header.
    const int rows = 64, cols = 48;
    std::vector<double> values(rows * cols);
    for (std::size_t k = 0; k < values.size(); ++k)
        values[k] = std::sin(0.37 * static_cast<double>(k)) * 1e3 + static_cast<double>(k);
    const std::string path = file("cut.exr");
    wavebrdf::write_heightfield_exr(path, Heightfield(rows, cols, values));
    const auto size = fs::file_size(path);
    fs::resize_file(path, size / 2);
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

// Issue 9: a 1.6 MB file declaring 20000² pixels took 4.7 GB and failed with std::bad_alloc.
// The header alone (no pixels written) declares the size; the reader must refuse it before
// allocating, naming the file, the declared size and the limit.
TEST_F(IoTest, HugeDeclaredSizeIsRefusedBeforeAllocating) {
    const std::string path = file("huge.exr");
    {
        Imf::Header header(20000, 20000);
        header.channels().insert("R", Imf::Channel(Imf::FLOAT));
        Imf::OutputFile out(path.c_str(), header);  // closed without pixels: header + offsets
    }
    ASSERT_LT(fs::file_size(path), 1u << 20);
    for (const auto& read : {std::function<void()>([&] { wavebrdf::read_heightfield_exr(path); }),
                             std::function<void()>([&] { wavebrdf::read_rgb_exr(path); })}) {
        try {
            read();
            ADD_FAILURE() << "no exception for " << path;
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("20000x20000"), std::string::npos) << message;
            EXPECT_NE(message.find(std::to_string(wavebrdf::k_max_exr_pixels)), std::string::npos) << message;
        } catch (const std::exception& e) {
            ADD_FAILURE() << "wrong exception type: " << e.what();
        }
    }
}

// Found by fuzz/exr_fuzz.cpp: OpenEXR 3.1 allocates a header attribute at its declared size
// (here 2 GB, from a 357-byte file) before reading it. The reader refuses it first, naming it.
TEST_F(IoTest, ExrAttributeLargerThanTheFileIsRefusedBeforeAllocating) {
    const std::string path = file("huge_attribute.exr");
    wavebrdf::write_heightfield_exr(path, make_field(4, 4));
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    // pixelAspectRatio becomes an attribute OpenEXR does not know, "qixelAspectRatio" of type
    // "xloat", declaring 2^31 - 1 bytes.
    const std::string attribute("pixelAspectRatio\0float\0", 23);
    const std::size_t at = bytes.find(attribute);
    ASSERT_NE(at, std::string::npos);
    bytes[at] = 'q';
    bytes[at + 17] = 'x';
    bytes.replace(at + attribute.size(), 4, std::string("\xff\xff\xff\x7f", 4));
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << bytes;
    }
    for (const auto& read : {+[](const std::string& p) { wavebrdf::read_heightfield_exr(p); },
                             +[](const std::string& p) { wavebrdf::read_rgb_exr(p); }}) {
        try {
            read(path);
            ADD_FAILURE() << "no exception";
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("'qixelAspectRatio' (type 'xloat') declares 2147483647 bytes"), std::string::npos)
                << message;
        }
    }
}

TEST_F(IoTest, ExrWithoutRedOrLuminanceThrowsNamingPath) {
    const std::string path = file("green.exr");
    write_exr_channel(path, "G", 2, 2, 0, 0, {1.0f, 2.0f, 3.0f, 4.0f});
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
    expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
}

TEST_F(IoTest, NonFiniteValueThrowsDomainErrorNamingPath) {
    const std::string path = file("nan.exr");
    write_exr_channel(path, "R", 2, 2, 0, 0, {1.0f, std::numeric_limits<float>::quiet_NaN(), 3.0f, 4.0f});
    expect_throw_naming<std::domain_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
}

TEST_F(IoTest, FailedWritesLeaveNoFileBehind) {
    const Heightfield field = make_field(3, 4);
    const RgbImage image{1, 2, {0.f, 0.5f, 1.f, 2.f, 3.f, 4.f}};
    // A missing directory, and a "directory" that is a regular file (fails even for root).
    std::ofstream(file("plain")) << "x";
    for (const std::string& dir : {file("missing"), file("plain")}) {
        const std::string path = dir + "/out";
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::write_heightfield_exr(path + ".exr", field); },
                                                path + ".exr");
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::write_heightfield_png(path + ".png", field); },
                                                path + ".png");
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::write_rgb_exr(path + ".exr", image, true); },
                                                path + ".exr");
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::write_rgb_png(path + ".png", image); }, path + ".png");
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::check_writable(path + ".exr"); }, path + ".exr");
    }
    EXPECT_FALSE(fs::exists(file("missing")));
    EXPECT_EQ(listing(), std::vector<std::string>{"plain"});
}

TEST_F(IoTest, RenameOntoDirectoryFailsAndRemovesTemporary) {
    // The temporary is written fine; only the final rename fails, which must clean up too.
    fs::create_directory(file("taken.exr"));
    fs::create_directory(file("taken.exr") + "/inside");
    expect_throw_naming<std::runtime_error>(
        [&] { wavebrdf::write_heightfield_exr(file("taken.exr"), make_field(2, 2)); }, file("taken.exr"));
    EXPECT_EQ(listing(), std::vector<std::string>{"taken.exr"});
}

TEST_F(IoTest, CheckWritableLeavesNothing) {
    wavebrdf::check_writable(file("later.exr"));
    EXPECT_TRUE(listing().empty());
}

// ---------------------------------------------------------------------------------------------
// Atomic writes replace only regular files, never mix, and leave no temporary behind.

// The file type bits of `path` itself (a link is not followed); 0 when it does not exist.
mode_t file_type(const std::string& path) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0 ? (st.st_mode & S_IFMT) : 0;
}

// Every writer on `path`, each expected to refuse with the path and "not a regular file".
void expect_every_writer_refuses(const std::string& path) {
    const Heightfield field = make_field(2, 3);
    const RgbImage image{1, 2, {0.f, 0.5f, 1.f, 2.f, 3.f, 4.f}};
    const std::vector<std::function<void()>> writers = {
        [&] { wavebrdf::write_text_atomically(path, "text\n"); },
        [&] { wavebrdf::write_file_atomically(path, [](const std::string& tmp) { std::ofstream(tmp) << "x"; }); },
        [&] { wavebrdf::write_heightfield_exr(path, field); },
        [&] { wavebrdf::write_heightfield_png(path, field); },
        [&] { wavebrdf::write_rgb_exr(path, image, true); },
        [&] { wavebrdf::write_rgb_png(path, image); },
        [&] {
            wavebrdf::write_npy(path, {2}, {1.0, 2.0});
        },
        [&] { wavebrdf::check_writable(path); },
    };
    for (std::size_t k = 0; k < writers.size(); ++k) {
        SCOPED_TRACE("writer " + std::to_string(k));
        try {
            writers[k]();
            ADD_FAILURE() << "no exception for " << path;
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("not a regular file; refusing to replace it"), std::string::npos) << message;
        }
    }
}

TEST_F(IoTest, WritersRefuseFifoSymlinkDirectoryAndSocket) {
    std::ofstream(file("target.txt")) << "keep me\n";
    ASSERT_EQ(::mkfifo(file("fifo").c_str(), 0644), 0);
    fs::create_symlink(file("target.txt"), file("link"));
    fs::create_symlink(file("missing.txt"), file("dangling"));
    fs::create_directory(file("dir"));
    const int sock = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    const std::string socket_path = file("sock");
    const bool have_socket = sock >= 0 && socket_path.size() < sizeof address.sun_path;
    if (have_socket) {
        std::memcpy(address.sun_path, socket_path.c_str(), socket_path.size() + 1);
        ASSERT_EQ(::bind(sock, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
    }
    for (const char* name : {"fifo", "link", "dangling", "dir", "sock"}) {
        SCOPED_TRACE(name);
        if (std::string(name) == "sock" && !have_socket) continue;
        const mode_t before = file_type(file(name));
        expect_every_writer_refuses(file(name));
        EXPECT_EQ(file_type(file(name)), before) << "the target was replaced";
    }
    if (sock >= 0) ::close(sock);
    EXPECT_EQ(fs::read_symlink(file("link")), fs::path(file("target.txt")));
    std::ifstream in(file("target.txt"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, "keep me\n") << "wrote through the link";
    EXPECT_FALSE(fs::exists(file("missing.txt"))) << "created the dangling link's target";
    EXPECT_TRUE(fs::is_empty(file("dir")));
    for (const std::string& name : listing()) EXPECT_EQ(name.find(".tmp"), std::string::npos) << name;
}

// A character device like /dev/null, made here (root only) so that a broken writer could only
// replace a node of this test's own directory, never the machine's /dev/null.
TEST_F(IoTest, WritersRefuseACharacterDevice) {
    const std::string node = file("null");
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0)
        GTEST_SKIP() << "cannot create a device node here (not root?)";
    ASSERT_EQ(file_type(node), static_cast<mode_t>(S_IFCHR));
    expect_every_writer_refuses(node);
    EXPECT_EQ(file_type(node), static_cast<mode_t>(S_IFCHR)) << "the device node was replaced";
    EXPECT_EQ(listing(), std::vector<std::string>{"null"});
}

TEST_F(IoTest, WriteTextReplacesARegularFile) {
    const std::string path = file("run.json");
    std::ofstream(path) << "old contents, longer than the new\n";
    wavebrdf::write_text_atomically(path, "new\n");
    std::ifstream in(path);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, "new\n");
    EXPECT_EQ(listing(), std::vector<std::string>{"run.json"});
}

// Threads of one process and two processes write the same path at once: every read sees one
// writer's whole file (the last rename wins), and no temporary is left. (With one fixed
// `<path>.tmp` name, two writers wrote into one temporary and mixed their contents.)
TEST_F(IoTest, ConcurrentWritersNeverMixAndLeaveNoTemporary) {
    const std::string path = file("metrics.csv");
    const std::size_t size = 1 << 18;
    auto writer = [&](char letter, int count) {
        const std::string text(size, letter);
        for (int k = 0; k < count; ++k) wavebrdf::write_text_atomically(path, text);
    };
    // Every complete read is one letter, `size` times.
    auto uniform = [&](const std::string& text) {
        return text.size() == size && text.find_first_not_of(text[0]) == std::string::npos;
    };
    auto read_all = [&] {
        std::ifstream in(path, std::ios::binary);
        return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    writer('z', 1);

    std::atomic<bool> done{false};
    std::atomic<int> mixed{0};
    std::thread reader([&] {
        while (!done.load())
            if (!uniform(read_all())) ++mixed;
    });
    {
        std::vector<std::thread> threads;
        for (char letter : {'a', 'b', 'c'}) threads.emplace_back(writer, letter, 20);
        for (std::thread& t : threads) t.join();
    }
    // Two processes (forked children write 'p' and 'q').
    std::vector<pid_t> children;
    for (char letter : {'p', 'q'}) {
        const pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            try {
                writer(letter, 20);
            } catch (...) {
                std::_Exit(1);
            }
            std::_Exit(0);
        }
        children.push_back(pid);
    }
    for (pid_t pid : children) {
        int status = 0;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child " << pid << " failed";
    }
    done.store(true);
    reader.join();
    EXPECT_EQ(mixed.load(), 0) << "a read saw a mixed or partial file";
    EXPECT_TRUE(uniform(read_all()));
    EXPECT_EQ(listing(), std::vector<std::string>{"metrics.csv"});
}

// A write that fails part way, or whose directory disappears before the rename, leaves no
// temporary and (where it still exists) the old file unchanged.
TEST_F(IoTest, FailedWriteLeavesNoTemporary) {
    const std::string path = file("checkpoint.json");
    std::ofstream(path) << "old\n";
    EXPECT_THROW(wavebrdf::write_file_atomically(path,
                                                 [](const std::string& tmp) {
                                                     std::ofstream(tmp) << "half";
                                                     throw std::runtime_error("disk full");
                                                 }),
                 std::runtime_error);
    EXPECT_EQ(listing(), std::vector<std::string>{"checkpoint.json"});

    const fs::path sub = m_dir / "sub";
    fs::create_directory(sub);
    const std::string inside = (sub / "metrics.csv").string();
    expect_throw_naming<std::runtime_error>(
        [&] {
            wavebrdf::write_file_atomically(inside, [&](const std::string& tmp) {
                std::ofstream(tmp) << "data";
                fs::remove_all(sub);  // the run directory removed while the file is written
            });
        },
        inside);
    EXPECT_FALSE(fs::exists(sub));

    // A directory without write permission (root may write anyway: skipped then).
    fs::create_directory(sub);
    fs::permissions(sub, fs::perms::owner_read | fs::perms::owner_exec);
    if (::geteuid() != 0) {
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::write_text_atomically(inside, "x"); }, inside);
        EXPECT_TRUE(fs::is_empty(sub));
    }
    fs::permissions(sub, fs::perms::owner_all);
    std::vector<std::string> names = listing();
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"checkpoint.json", "sub"}));
    EXPECT_TRUE(fs::is_empty(sub));
    std::ifstream in(path);
    EXPECT_EQ(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()), "old\n");
}

// A process killed by a signal in the middle of a write: its handler calls
// remove_temporary_files(), and the temporary is gone.
extern "C" void remove_temporaries_and_exit(int) {
    wavebrdf::remove_temporary_files();
    ::_exit(3);
}

TEST_F(IoTest, SignalHandlerRemovesTheTemporaryOfAWriteInProgress) {
    const std::string path = file("estimate.exr");
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ::close(ready[0]);
        ::signal(SIGTERM, remove_temporaries_and_exit);
        ::alarm(60);  // never outlive a broken test
        try {
            wavebrdf::write_file_atomically(path, [&](const std::string& tmp) {
                std::ofstream(tmp) << "half-written";
                const char byte = 1;
                if (::write(ready[1], &byte, 1) != 1) std::_Exit(1);
                for (;;) ::pause();  // "still writing" until the signal comes
            });
        } catch (...) {}
        std::_Exit(2);
    }
    ::close(ready[1]);
    char byte = 0;
    ASSERT_EQ(::read(ready[0], &byte, 1), 1);
    ::close(ready[0]);
    bool temporary_seen = false;
    for (const std::string& name : listing()) temporary_seen |= name.rfind("estimate.exr.tmp-", 0) == 0;
    EXPECT_TRUE(temporary_seen) << "the child's temporary should exist while it writes";
    ASSERT_EQ(::kill(pid, SIGTERM), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 3);
    EXPECT_TRUE(listing().empty()) << "left: " << (listing().empty() ? "" : listing()[0]);
}

// A multi-part EXR: the reader used to read part 0 silently; it refuses and says why.
void write_multi_part_exr(const std::string& path, int parts) {
    const int rows = 2, cols = 3;
    std::vector<float> values(static_cast<std::size_t>(rows * cols), 0.5f);
    std::vector<Imf::Header> headers;
    for (int p = 0; p < parts; ++p) {
        Imf::Header header(cols, rows);
        header.setName("part" + std::to_string(p));
        header.setType(Imf::SCANLINEIMAGE);
        for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        headers.push_back(header);
    }
    Imf::MultiPartOutputFile out(path.c_str(), headers.data(), parts);
    for (int p = 0; p < parts; ++p) {
        Imf::OutputPart part(out, p);
        Imf::FrameBuffer frame;
        for (const char* c : {"R", "G", "B"})
            frame.insert(c, Imf::Slice::Make(Imf::FLOAT, values.data(), headers[p].dataWindow()));
        part.setFrameBuffer(frame);
        part.writePixels(rows);
    }
}

TEST_F(IoTest, MultiPartExrIsRefused) {
    const std::string path = file("parts.exr");
    write_multi_part_exr(path, 2);
    for (int reader = 0; reader < 2; ++reader) {
        try {
            if (reader == 0)
                wavebrdf::read_heightfield_exr(path);
            else
                wavebrdf::read_rgb_exr(path);
            ADD_FAILURE() << "a multi-part file was read";
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find("multi-part"), std::string::npos) << message;
            EXPECT_NE(message.find("2 parts"), std::string::npos) << message;
        }
    }
    // One part written through the multi-part API is an ordinary image.
    write_multi_part_exr(file("one.exr"), 1);
    EXPECT_EQ(wavebrdf::read_rgb_exr(file("one.exr")).cols, 3);
}

TEST_F(IoTest, RgbPngHasSizeAndSrgbValues) {
    // 0.5 linear → sRGB 0.7354 → 188; 0.001 is on the linear segment → 0.01292 → 3.
    RgbImage image{2, 3, std::vector<float>(18, 0.0f)};
    auto px = [&](int i, int j, int c) -> float& { return image.data[(i * 3 + j) * 3 + c]; };
    px(0, 0, 0) = 0.5f;
    px(0, 0, 1) = 0.001f;
    px(0, 0, 2) = 7.0f;  // clamps to white
    px(1, 2, 0) = std::numeric_limits<float>::quiet_NaN();
    px(1, 2, 1) = std::numeric_limits<float>::infinity();
    px(1, 2, 2) = -3.0f;
    px(0, 1, 0) = 0.25f;  // exposure +1 → 0.5 → 188; with Reinhard 1/3 → 0.6125 → 156
    const std::string path = file("img.png");
    wavebrdf::write_rgb_png(path, image);
    Png png = read_png(path, true);
    ASSERT_EQ(png.rows, 2);
    ASSERT_EQ(png.cols, 3);
    auto at = [&](int i, int j, int c) { return static_cast<int>(png.pixels[(i * 3 + j) * 3 + c]); };
    EXPECT_EQ(at(0, 0, 0), 188);
    EXPECT_EQ(at(0, 0, 1), 3);
    EXPECT_EQ(at(0, 0, 2), 255);
    EXPECT_EQ(at(1, 2, 0), 0);
    EXPECT_EQ(at(1, 2, 1), 0);
    EXPECT_EQ(at(1, 2, 2), 0);
    EXPECT_EQ(at(0, 1, 0), 137);  // 0.25 → 0.5371 → 137

    wavebrdf::write_rgb_png(path, image, 1.0);
    png = read_png(path, true);
    EXPECT_EQ(at(0, 1, 0), 188);
    wavebrdf::write_rgb_png(path, image, 1.0, true);
    png = read_png(path, true);
    EXPECT_EQ(at(0, 1, 0), 156);
    EXPECT_EQ(listing(), std::vector<std::string>{"img.png"});
}

TEST_F(IoTest, HeightfieldPngStretchesMinToMax) {
    const Heightfield field(2, 3, {-1.0, 0.0, 1.0, 3.0, -1.0, 0.5});
    const std::string path = file("h.png");
    wavebrdf::write_heightfield_png(path, field);
    Png png = read_png(path, false);
    ASSERT_EQ(png.rows, 2);
    ASSERT_EQ(png.cols, 3);
    EXPECT_EQ(png.pixels, (std::vector<std::uint8_t>{0, 64, 128, 255, 0, 96}));

    wavebrdf::write_heightfield_png(path, Heightfield(1, 2, {4.0, 4.0}));
    png = read_png(path, false);
    EXPECT_EQ(png.pixels, (std::vector<std::uint8_t>{128, 128}));
}

TEST_F(IoTest, InvalidImageArgumentsThrow) {
    const std::string path = file("bad.png");
    EXPECT_THROW(wavebrdf::write_rgb_png(path, RgbImage{2, 2, std::vector<float>(5)}), std::invalid_argument);
    EXPECT_THROW(wavebrdf::write_rgb_exr(file("bad.exr"), RgbImage{0, 2, {}}), std::invalid_argument);
    EXPECT_THROW(wavebrdf::write_rgb_png(path, RgbImage{1, 1, {0.f, 0.f, 0.f}}, std::nan("")), std::domain_error);
    EXPECT_TRUE(listing().empty());
}

}  // namespace

// Found by fuzz/exr_fuzz.cpp: OpenEXR sizes line-offset tables, compressor and tile buffers from
// the header when it opens a file (up to 1.2 GB from 133 bytes). Each saved input is refused
// before it is opened, with a runtime_error naming the file.
TEST_F(IoTest, FuzzerFoundExrHeadersAreRefusedBeforeOpening) {
    const fs::path dir = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "regressions" / "exr";
    int seen = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string path = entry.path().string();
        ++seen;
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_heightfield_exr(path); }, path);
        expect_throw_naming<std::runtime_error>([&] { wavebrdf::read_rgb_exr(path); }, path);
    }
    EXPECT_GE(seen, 5);
}
