#include "core/keys.h"

#include <openssl/evp.h>

#include <array>
#include <memory>

#include "core/deck.h"

namespace sandswim {
namespace {

// Fields are length-prefixed so that no two different tuples hash the same bytes.
class Hasher {
 public:
  Hasher() : ctx_(EVP_MD_CTX_new(), EVP_MD_CTX_free) { EVP_DigestInit_ex(ctx_.get(), EVP_sha256(), nullptr); }
  Hasher& Raw(std::string_view bytes) {
    EVP_DigestUpdate(ctx_.get(), bytes.data(), bytes.size());
    return *this;
  }
  Hasher& Field(std::string_view bytes) {
    std::string len = std::to_string(bytes.size()) + ":";
    EVP_DigestUpdate(ctx_.get(), len.data(), len.size());
    EVP_DigestUpdate(ctx_.get(), bytes.data(), bytes.size());
    return *this;
  }
  std::string Hex() {
    std::array<unsigned char, EVP_MAX_MD_SIZE> md{};
    unsigned int n = 0;
    EVP_DigestFinal_ex(ctx_.get(), md.data(), &n);
    static const char kHex[] = "0123456789abcdef";
    std::string out;
    for (unsigned int i = 0; i < n; ++i) {
      out += kHex[md[i] >> 4];
      out += kHex[md[i] & 15];
    }
    return out;
  }

 private:
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx_;
};

}  // namespace

std::string Sha256Hex(std::string_view bytes) { return Hasher().Raw(bytes).Hex(); }

std::string BedKey(std::string_view bed_deck, std::string_view engine_version) {
  return Hasher()
      .Field("sandswim-bed")
      .Field(std::to_string(kTemplateVersion))
      .Field(engine_version)
      .Field(bed_deck)
      .Hex();
}

std::string RunKey(std::string_view drive_deck, std::string_view bed_key, std::string_view engine_version) {
  return Hasher()
      .Field("sandswim-run")
      .Field(std::to_string(kTemplateVersion))
      .Field(engine_version)
      .Field(bed_key)
      .Field(drive_deck)
      .Hex();
}

}  // namespace sandswim
