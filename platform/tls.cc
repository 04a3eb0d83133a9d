#include "platform/tls.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstring>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <mutex>

#include <httplib.h>
#include <openssl/bn.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include "core/text.h"
#include "platform/token.h"

namespace sandswim {

namespace {

template <typename T, void (*Free)(T*)>
struct Freer {
  void operator()(T* p) const { Free(p); }
};
using X509Ptr = std::unique_ptr<X509, Freer<X509, X509_free>>;
using PkeyPtr = std::unique_ptr<EVP_PKEY, Freer<EVP_PKEY, EVP_PKEY_free>>;
using BioPtr = std::unique_ptr<BIO, Freer<BIO, BIO_free_all>>;

std::string OpenSslError() {
  const unsigned long e = ERR_get_error();
  if (e == 0) return "no detail from OpenSSL";
  char text[256];
  ERR_error_string_n(e, text, sizeof text);
  ERR_clear_error();
  return text;
}

Result<X509Ptr> ReadCertificate(const std::string& path) {
  BioPtr bio(BIO_new_file(path.c_str(), "r"));
  if (!bio) return Status::InvalidArgument("--tls-cert", "cannot read " + path + ": " + OpenSslError());
  X509Ptr cert(PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr));
  if (!cert) return Status::InvalidArgument("--tls-cert", path + " holds no PEM certificate: " + OpenSslError());
  return cert;
}

std::string FingerprintOf(X509* cert) {
  const int size = i2d_X509(cert, nullptr);
  if (size <= 0) return "";
  std::string der(static_cast<size_t>(size), '\0');
  unsigned char* out = reinterpret_cast<unsigned char*>(der.data());
  i2d_X509(cert, &out);
  return FingerprintOfDer(reinterpret_cast<const unsigned char*>(der.data()), der.size());
}

// The private key file: not a link, a regular file of this user that no one else may read
// (platform/token.h's rule for the token file).
Status CheckPrivateFile(const std::string& path, const std::string& field) {
  const int fd = open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) {
    return Status::InvalidArgument(field, "cannot open " + path + ": " + std::strerror(errno) +
                                              (errno == ELOOP ? " (a symbolic link: give the file itself)" : ""));
  }
  Status s = CheckPrivateFd(fd, path, field);
  close(fd);
  return s;
}

// Writes `text` to a new file `path` with `mode` (O_EXCL: never over another's file), synced.
Status WriteNewFile(const std::string& path, const std::string& text, mode_t mode) {
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode);
  if (fd < 0) return Status::IOError("cannot create " + path + ": " + std::strerror(errno));
  const bool written = write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) && fsync(fd) == 0;
  close(fd);
  if (!written) {
    unlink(path.c_str());
    return Status::IOError("cannot write " + path + " (disk full?)");
  }
  return Status::Ok();
}

std::string PemOf(int (*write)(BIO*, void*), void* object) {
  BioPtr bio(BIO_new(BIO_s_mem()));
  if (!bio || write(bio.get(), object) != 1) return "";
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio.get(), &data);
  return std::string(data, static_cast<size_t>(n));
}

int WriteKey(BIO* bio, void* key) {
  return PEM_write_bio_PrivateKey(bio, static_cast<EVP_PKEY*>(key), nullptr, nullptr, 0, nullptr, nullptr);
}
int WriteCert(BIO* bio, void* cert) { return PEM_write_bio_X509(bio, static_cast<X509*>(cert)); }

// subjectAltName entries: DNS:NAME or IP:ADDRESS, without duplicates.
std::string AltNames(const std::vector<std::string>& names) {
  std::vector<std::string> all = {"localhost", "127.0.0.1", "::1"};
  for (const std::string& n : names) {
    std::string name = n;
    if (name.size() >= 2 && name.front() == '[' && name.back() == ']') name = name.substr(1, name.size() - 2);
    if (name.empty() || name == "0.0.0.0" || name == "::") continue;
    bool ok = true;
    for (char c : name) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == ':');
    if (ok && std::find(all.begin(), all.end(), name) == all.end()) all.push_back(name);
  }
  std::string out;
  for (const std::string& name : all) {
    in_addr v4{};
    in6_addr v6{};
    const bool ip = inet_pton(AF_INET, name.c_str(), &v4) == 1 || inet_pton(AF_INET6, name.c_str(), &v6) == 1;
    if (!ip && name.find(':') != std::string::npos) continue;
    if (!out.empty()) out += ",";
    out += (ip ? "IP:" : "DNS:") + name;
  }
  return out;
}

Result<TlsFiles> MakeSelfSigned(const std::string& cert_path, const std::string& key_path,
                                const std::vector<std::string>& names) {
  PkeyPtr key(EVP_EC_gen("P-256"));
  if (!key) return Status::Internal("cannot make an EC key: " + OpenSslError());
  X509Ptr cert(X509_new());
  X509_set_version(cert.get(), 2);
  std::unique_ptr<BIGNUM, Freer<BIGNUM, BN_free>> serial(BN_new());
  BN_rand(serial.get(), 63, BN_RAND_TOP_ANY, BN_RAND_BOTTOM_ANY);
  BN_to_ASN1_INTEGER(serial.get(), X509_get_serialNumber(cert.get()));
  X509_gmtime_adj(X509_getm_notBefore(cert.get()), -3600);  // clocks a little behind
  X509_gmtime_adj(X509_getm_notAfter(cert.get()), 10L * 365 * 86400);
  X509_set_pubkey(cert.get(), key.get());
  X509_NAME* subject = X509_get_subject_name(cert.get());
  X509_NAME_add_entry_by_txt(subject, "O", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("sandswim"), -1, -1,
                             0);
  X509_NAME_add_entry_by_txt(subject, "CN", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("sandswimd"), -1,
                             -1, 0);
  X509_set_issuer_name(cert.get(), subject);
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, cert.get(), cert.get(), nullptr, nullptr, 0);
  const std::string alt = AltNames(names);
  X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &ctx, NID_subject_alt_name, alt.c_str());
  if (ext == nullptr) return Status::Internal("cannot name " + alt + " in a certificate: " + OpenSslError());
  X509_add_ext(cert.get(), ext, -1);
  X509_EXTENSION_free(ext);
  if (X509_sign(cert.get(), key.get(), EVP_sha256()) == 0) return Status::Internal("cannot sign: " + OpenSslError());

  // The key first, so that a certificate on disk always has its key.
  if (Status s = WriteNewFile(key_path, PemOf(WriteKey, key.get()), 0600); !s.ok()) return s;
  if (Status s = WriteNewFile(cert_path, PemOf(WriteCert, cert.get()), 0644); !s.ok()) {
    unlink(key_path.c_str());
    return s;
  }
  TlsFiles out;
  out.cert = cert_path;
  out.key = key_path;
  out.fingerprint = FingerprintOf(cert.get());
  out.created = true;
  return out;
}

// A client's pinned fingerprint and what the daemon presented, kept in the client's SSL context.
struct Pin {
  std::string expected;
  std::mutex mu;
  std::string seen;  // the last mismatching certificate's fingerprint
};

void FreePin(void*, void* ptr, CRYPTO_EX_DATA*, int, long, void*) { delete static_cast<Pin*>(ptr); }

int PinIndex() {
  static const int index = SSL_CTX_get_ex_new_index(0, nullptr, nullptr, nullptr, FreePin);
  return index;
}

// The chain is not looked at, only the daemon's own certificate (depth 0): it must be the pinned one.
int VerifyPinned(int /*preverified*/, X509_STORE_CTX* store) {
  if (X509_STORE_CTX_get_error_depth(store) != 0) return 1;
  SSL* ssl = static_cast<SSL*>(X509_STORE_CTX_get_ex_data(store, SSL_get_ex_data_X509_STORE_CTX_idx()));
  Pin* pin = ssl ? static_cast<Pin*>(SSL_CTX_get_ex_data(SSL_get_SSL_CTX(ssl), PinIndex())) : nullptr;
  X509* cert = X509_STORE_CTX_get_current_cert(store);
  if (pin == nullptr || cert == nullptr) return 0;
  const std::string seen = FingerprintOf(cert);
  std::lock_guard<std::mutex> lock(pin->mu);
  if (seen == pin->expected) {
    pin->seen.clear();
    X509_STORE_CTX_set_error(store, X509_V_OK);
    return 1;
  }
  pin->seen = seen;
  X509_STORE_CTX_set_error(store, X509_V_ERR_CERT_REJECTED);
  return 0;
}

}  // namespace

std::string FingerprintOfDer(const unsigned char* der, size_t size) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  EVP_Digest(der, size, digest, &n, EVP_sha256(), nullptr);
  static const char kHex[] = "0123456789ABCDEF";
  std::string out = "SHA256:";
  for (unsigned int i = 0; i < n; ++i) {
    if (i > 0) out += ':';
    out += kHex[digest[i] >> 4];
    out += kHex[digest[i] & 15];
  }
  return out;
}

Result<std::string> CertificateFingerprint(const std::string& pem_path) {
  auto cert = ReadCertificate(pem_path);
  if (!cert.ok()) return cert.status();
  return FingerprintOf(cert->get());
}

Result<std::string> ParseFingerprint(const std::string& text_in, const std::string& field) {
  std::string text(Trim(text_in));
  std::string lower;
  for (char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* prefix : {"sha256:", "sha256=", "sha256 fingerprint="}) {
    if (lower.rfind(prefix, 0) == 0) {
      text = text.substr(std::strlen(prefix));
      break;
    }
  }
  std::string hex;
  for (char c : text) {
    if (c == ':') continue;
    if (!std::isxdigit(static_cast<unsigned char>(c))) {
      hex.clear();
      break;
    }
    hex += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  if (hex.size() != 64) {
    return Status::InvalidArgument(
        field, "expected a SHA-256 fingerprint, SHA256: and 32 byte pairs (the daemon prints it at start; "
               "openssl x509 -noout -fingerprint -sha256 -in CERT shows it), got \"" + text_in + "\"");
  }
  std::string out = "SHA256:";
  for (size_t i = 0; i < hex.size(); i += 2) {
    if (i > 0) out += ':';
    out += hex.substr(i, 2);
  }
  return out;
}

std::string SelfSignedCertificate(const std::string& tls_dir) { return tls_dir + "/cert.pem"; }

Result<TlsFiles> CheckCertificateFiles(const std::string& cert_path, const std::string& key_path) {
  auto cert = ReadCertificate(cert_path);
  if (!cert.ok()) return cert.status();
  if (Status s = CheckPrivateFile(key_path, "--tls-key"); !s.ok()) return s;
  BioPtr bio(BIO_new_file(key_path.c_str(), "r"));
  PkeyPtr key(bio ? PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr) : nullptr);
  if (!key) return Status::InvalidArgument("--tls-key", key_path + " holds no PEM private key: " + OpenSslError());
  if (X509_check_private_key(cert->get(), key.get()) != 1) {
    return Status::InvalidArgument("--tls-key", key_path + " is not the key of the certificate in " + cert_path);
  }
  TlsFiles out;
  out.cert = cert_path;
  out.key = key_path;
  out.fingerprint = FingerprintOf(cert->get());
  return out;
}

Result<TlsFiles> LoadOrCreateSelfSigned(const std::string& dir, const std::vector<std::string>& names) {
  const std::string cert = SelfSignedCertificate(dir), key = dir + "/key.pem";
  const bool have_cert = access(cert.c_str(), F_OK) == 0, have_key = access(key.c_str(), F_OK) == 0;
  if (have_cert && have_key) {
    auto files = CheckCertificateFiles(cert, key);
    if (!files.ok()) {
      return Status::FailedPrecondition(
          "--tls", files.status().reason() + " (the self-signed certificate in " + dir +
                       ": fix it, or remove both files and a new one is made)");
    }
    return files;
  }
  if (have_cert != have_key) {
    return Status::FailedPrecondition("--tls", "only one of " + cert + " and " + key +
                                                   " exists: remove it and a new certificate is made");
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Status::IOError("cannot create " + dir + ": " + ec.message());
  return MakeSelfSigned(cert, key, names);
}

Result<TlsTrust> ResolveTlsTrust(const std::string& fingerprint_flag, const std::string& ca_flag,
                                 const std::function<const char*(const char*)>& getenv) {
  TlsTrust trust;
  auto from = [&](const std::string& flag, const char* env, std::string* field) {
    *field = flag.empty() ? env : "";
    if (!flag.empty()) return flag;
    const char* value = getenv(env);
    return std::string(value ? value : "");
  };
  std::string fingerprint_field, ca_field;
  const std::string fingerprint = from(fingerprint_flag, "SANDSWIM_TLS_FINGERPRINT", &fingerprint_field);
  const std::string ca = from(ca_flag, "SANDSWIM_TLS_CA", &ca_field);
  if (!fingerprint.empty()) {
    auto parsed = ParseFingerprint(fingerprint, fingerprint_field.empty() ? "--tls-fingerprint" : fingerprint_field);
    if (!parsed.ok()) return parsed.status();
    trust.fingerprint = *parsed;
  }
  if (!ca.empty()) {
    if (access(ca.c_str(), R_OK) != 0) {
      return Status::InvalidArgument(ca_field.empty() ? "--tls-ca" : ca_field,
                                     "cannot read " + ca + ": " + std::strerror(errno));
    }
    trust.ca_file = ca;
  }
  return trust;
}

void ConfigureTls(httplib::Client& client, const TlsTrust& trust) {
  SSL_CTX* ctx = client.ssl_context();
  if (ctx == nullptr) return;  // http://
  if (!trust.fingerprint.empty()) {
    // The library's own check (a chain to a CA, the host's name) is off; the pin replaces it.
    client.enable_server_certificate_verification(false);
    auto* pin = new Pin;
    pin->expected = trust.fingerprint;
    SSL_CTX_set_ex_data(ctx, PinIndex(), pin);
    SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER, VerifyPinned);
    return;
  }
  client.enable_server_certificate_verification(true);
  if (!trust.ca_file.empty()) client.set_ca_cert_path(trust.ca_file);
}

std::optional<Status> TlsFailure(const httplib::Client& client, int error_in, const std::string& server) {
  const auto error = static_cast<httplib::Error>(error_in);
  SSL_CTX* ctx = client.ssl_context();
  if (ctx == nullptr) return std::nullopt;
  if (auto* pin = static_cast<Pin*>(SSL_CTX_get_ex_data(ctx, PinIndex())); pin != nullptr) {
    std::lock_guard<std::mutex> lock(pin->mu);
    if (!pin->seen.empty()) {
      return Status(StatusCode::kUnauthenticated,
                    "the daemon at " + server + " presented a certificate with fingerprint " + pin->seen +
                        ", not the pinned " + pin->expected +
                        ": refusing to talk to it (someone may be in between; if the daemon's certificate was "
                        "replaced, pin the fingerprint it prints at start with --tls-fingerprint)",
                    "--tls-fingerprint");
    }
  }
  if (error == httplib::Error::SSLServerVerification) {
    const long why = client.get_openssl_verify_result();
    return Status(StatusCode::kUnauthenticated,
                  "the daemon at " + server + " presented a certificate this client does not trust (" +
                      (why != X509_V_OK ? X509_verify_cert_error_string(why)
                                        : "it does not name the host in the URL") +
                      "): pass --tls-ca FILE (its CA, or for a self-signed daemon DATA/tls/cert.pem), or pin it "
                      "with --tls-fingerprint SHA256:... as the daemon printed it at start",
                  "--tls-ca");
  }
  if (error == httplib::Error::SSLLoadingCerts) {
    return Status::InvalidArgument("--tls-ca", "cannot load the CA certificates to check the daemon's with: " +
                                                   OpenSslError());
  }
  if (error == httplib::Error::SSLConnection) {
    return Status::Unavailable("no TLS handshake with " + server +
                               " (does the daemon serve HTTPS? It does with --tls-cert/--tls-key or --tls "
                               "self-signed; else use http://)");
  }
  return std::nullopt;
}

}  // namespace sandswim
