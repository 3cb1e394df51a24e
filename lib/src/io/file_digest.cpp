#include "pcdp/io/file_digest.hpp"

#include <fcntl.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <cerrno>
#include <memory>
#include <vector>

namespace pcdp::io {

namespace {
struct MdCtxFree {
  void operator()(EVP_MD_CTX* c) const { EVP_MD_CTX_free(c); }
};
using MdCtx = std::unique_ptr<EVP_MD_CTX, MdCtxFree>;

std::string hex(const unsigned char* d, unsigned n) {
  static const char* digits = "0123456789abcdef";
  std::string s(2 * static_cast<std::size_t>(n), '0');
  for (unsigned i = 0; i < n; ++i) {
    s[2 * i] = digits[d[i] >> 4];
    s[2 * i + 1] = digits[d[i] & 15];
  }
  return s;
}

MdCtx sha256_context() {
  MdCtx c(EVP_MD_CTX_new());
  if (!c || EVP_DigestInit_ex(c.get(), EVP_sha256(), nullptr) != 1) throw std::bad_alloc();
  return c;
}

std::string finish(EVP_MD_CTX* c) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned n = 0;
  if (EVP_DigestFinal_ex(c, md, &n) != 1) throw std::bad_alloc();
  return hex(md, n);
}

struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};
}  // namespace

int digest_file(const std::string& path, FileDigest& out) {
  Fd f{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
  if (f.fd < 0) return errno;
  const MdCtx c = sha256_context();
  std::vector<unsigned char> buf(std::size_t{1} << 20);
  std::uint64_t total = 0;
  for (;;) {
    const ssize_t r = ::read(f.fd, buf.data(), buf.size());
    if (r < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (r == 0) break;
    if (EVP_DigestUpdate(c.get(), buf.data(), static_cast<std::size_t>(r)) != 1) throw std::bad_alloc();
    total += static_cast<std::uint64_t>(r);
  }
  out.bytes = total;
  out.sha256 = finish(c.get());
  return 0;
}

std::string sha256_hex(const void* data, std::size_t size) {
  const MdCtx c = sha256_context();
  if (EVP_DigestUpdate(c.get(), data, size) != 1) throw std::bad_alloc();
  return finish(c.get());
}

}  // namespace pcdp::io
