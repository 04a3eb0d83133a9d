// TLS for the daemon, its workers and the CLI: the daemon's certificate (the operator's, or one it
// makes for itself), its fingerprint, and how a client decides to trust the daemon.
//
// The daemon serves HTTPS with `--tls-cert FILE --tls-key FILE` (the operator's certificate) or
// `--tls self-signed`: then DATA/tls/cert.pem and DATA/tls/key.pem (mode 0600) are made on the
// first start (LoadOrCreateSelfSigned: an EC P-256 key, valid 10 years, for localhost, the
// loopback addresses and the names and addresses given) and reused later. Either way it prints
// the certificate's fingerprint (Fingerprint: "SHA256:" and 32 colon-separated byte pairs, as
// `openssl x509 -noout -fingerprint -sha256` prints them).
//
// A client (TlsTrust) trusts the daemon at an https:// URL by one of:
//  - a pinned fingerprint (--tls-fingerprint / $SANDSWIM_TLS_FINGERPRINT): the certificate the
//    daemon presents must be that one; names and issuers are not looked at (a self-signed
//    certificate, or the operator's on an address it does not name);
//  - a CA file (--tls-ca / $SANDSWIM_TLS_CA): the certificate must chain to it and name the host;
//  - else the system's CAs (/etc/ssl/certs), and the host name.
// ConfigureTls() sets that up on an HTTP client; TlsFailure() turns a failed connection into a
// Status that says what was wrong and what to do (a mismatch is never retried: it is not the
// daemon's trouble).
//
// Thread safety: free functions; the pinning state lives in the client's SSL context, one per client.
#ifndef SANDSWIM_PLATFORM_TLS_H_
#define SANDSWIM_PLATFORM_TLS_H_

#include <cstdlib>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/status.h"

namespace httplib {
class Client;
}

namespace sandswim {

// "SHA256:AB:CD:..." of a certificate's DER bytes.
std::string FingerprintOfDer(const unsigned char* der, size_t size);
// The fingerprint of the first certificate in a PEM file.
Result<std::string> CertificateFingerprint(const std::string& pem_path);
// A fingerprint as a user gives it -- with or without "SHA256:" (or "sha256="), colons, in any
// case -- in Fingerprint form; an error naming `field` otherwise.
Result<std::string> ParseFingerprint(const std::string& text, const std::string& field);

struct TlsFiles {
  std::string cert;  // PEM paths
  std::string key;
  std::string fingerprint;
  bool created = false;  // made on this start
};
// The self-signed certificate in a TLS directory (DataDir::Tls): TLS_DIR/cert.pem.
std::string SelfSignedCertificate(const std::string& tls_dir);
// Reads DIR/cert.pem and DIR/key.pem when both exist (the key must be a regular file of this user,
// not a link, mode 0600 or 0400), else makes them. `names`: more host names or IP addresses the
// certificate is for, besides localhost, 127.0.0.1 and ::1.
Result<TlsFiles> LoadOrCreateSelfSigned(const std::string& dir, const std::vector<std::string>& names);
// The operator's files: both readable, the key matches the certificate; the fingerprint filled in.
Result<TlsFiles> CheckCertificateFiles(const std::string& cert, const std::string& key);

// How a client trusts the daemon (see the top of this file). Empty: the system's CAs.
struct TlsTrust {
  std::string ca_file;
  std::string fingerprint;  // Fingerprint form
};
// --tls-fingerprint, else $SANDSWIM_TLS_FINGERPRINT; --tls-ca, else $SANDSWIM_TLS_CA.
Result<TlsTrust> ResolveTlsTrust(const std::string& fingerprint_flag, const std::string& ca_flag,
                                 const std::function<const char*(const char*)>& getenv = std::getenv);

// Sets up `client` (made for an https:// URL) to trust the daemon as `trust` says.
void ConfigureTls(httplib::Client& client, const TlsTrust& trust);
// After a request on `client` failed with httplib error `error` (an int: httplib::Error), the
// reason when it was TLS's: a pinned fingerprint not matched, a certificate not trusted, a
// handshake that failed (a plain-HTTP daemon at an https:// URL). nullopt for other failures.
std::optional<Status> TlsFailure(const httplib::Client& client, int error, const std::string& server);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_TLS_H_
