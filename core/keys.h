// Content keys: what makes a bed or a run the same as one already done.
//
// A bed's key hashes its rendered deck, the template version and the engine version; a run's key
// hashes its rendered drive deck, its bed's key, the template version and the engine version.
// Equal keys mean equal work, so a stored result under the key can be reused.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_KEYS_H_
#define SANDSWIM_CORE_KEYS_H_

#include <string>
#include <string_view>

namespace sandswim {

// Lower-case hex SHA-256 of the bytes.
std::string Sha256Hex(std::string_view bytes);

std::string BedKey(std::string_view bed_deck, std::string_view engine_version);
std::string RunKey(std::string_view drive_deck, std::string_view bed_key, std::string_view engine_version);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_KEYS_H_
