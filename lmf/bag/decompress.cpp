#include "lmf/bag/decompress.hpp"

#include <bzlib.h>
#include <lz4frame.h>
#include <zstd.h>

namespace lmf::bag {
namespace {

void check_bound(const std::string& codec, std::uint64_t size, std::uint64_t compressed, std::uint64_t ratio) {
  constexpr std::uint64_t kSlack = 1 << 20;
  if (size > ratio * compressed + kSlack) {
    throw std::runtime_error(codec + ": an uncompressed size of " + std::to_string(size) + " bytes is more than " +
                             std::to_string(compressed) + " compressed bytes can hold");
  }
}

void lz4(std::span<const std::uint8_t> in, std::vector<std::uint8_t>& out) {
  LZ4F_dctx* context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&context, LZ4F_VERSION)) != 0u) {
    throw std::runtime_error("lz4: no decompression context");
  }
  std::size_t written = 0, read = 0, status = 1;
  while (status != 0 && read < in.size() && written < out.size()) {
    std::size_t out_size = out.size() - written;
    std::size_t in_size = in.size() - read;
    status = LZ4F_decompress(context, out.data() + written, &out_size, in.data() + read, &in_size, nullptr);
    if (LZ4F_isError(status) != 0u) {
      LZ4F_freeDecompressionContext(context);
      throw std::runtime_error(std::string("lz4: ") + LZ4F_getErrorName(status));
    }
    written += out_size;
    read += in_size;
    if (out_size == 0 && in_size == 0) break;
  }
  LZ4F_freeDecompressionContext(context);
  if (written != out.size()) throw std::runtime_error("lz4: not the size announced");
}

}  // namespace

std::vector<std::uint8_t> decompress(const std::string& codec, std::span<const std::uint8_t> compressed,
                                     std::uint64_t uncompressed_size) {
  std::vector<std::uint8_t> out;
  if (codec == "zstd") {
    const unsigned long long stated = ZSTD_getFrameContentSize(compressed.data(), compressed.size());
    if (stated == ZSTD_CONTENTSIZE_ERROR) throw std::runtime_error("zstd: not a zstd frame");
    if (stated != ZSTD_CONTENTSIZE_UNKNOWN && stated != uncompressed_size) {
      throw std::runtime_error("zstd: the frame holds " + std::to_string(stated) + " bytes, the chunk says " +
                               std::to_string(uncompressed_size));
    }
    if (stated == ZSTD_CONTENTSIZE_UNKNOWN) check_bound(codec, uncompressed_size, compressed.size(), 1000);
    out.resize(static_cast<std::size_t>(uncompressed_size));
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), compressed.data(), compressed.size());
    if (ZSTD_isError(n) != 0u) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
    if (n != out.size()) throw std::runtime_error("zstd: not the size announced");
  } else if (codec == "lz4") {
    check_bound(codec, uncompressed_size, compressed.size(), 255);
    out.resize(static_cast<std::size_t>(uncompressed_size));
    lz4(compressed, out);
  } else if (codec == "bz2") {
    check_bound(codec, uncompressed_size, compressed.size(), 1000);
    out.resize(static_cast<std::size_t>(uncompressed_size));
    auto size = static_cast<unsigned int>(out.size());
    std::vector<char> source(compressed.begin(), compressed.end());  // libbz2 takes char*, not const
    const int rc = BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(out.data()), &size, source.data(),
                                              static_cast<unsigned int>(source.size()), 0, 0);
    if (rc != BZ_OK) throw std::runtime_error("bz2: error " + std::to_string(rc));
    if (size != out.size()) throw std::runtime_error("bz2: not the size announced");
  } else {
    throw std::runtime_error("unknown compression \"" + codec + "\"");
  }
  return out;
}

}  // namespace lmf::bag
