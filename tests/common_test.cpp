#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "common/fnv1a.h"

namespace distile {
namespace {

std::uint64_t fnv1a64Of(std::string_view text) {
    Fnv1a64 hash;
    hash.update(std::as_bytes(std::span(text)));
    return hash.value();
}

// The test vectors published with FNV (Noll's test_fnv.c, FNV-1a 64 column).
TEST(Fnv1a64, PublishedTestVectors) {
    EXPECT_EQ(fnv1a64Of(""), 0xcbf29ce484222325ull);
    EXPECT_EQ(fnv1a64Of("a"), 0xaf63dc4c8601ec8cull);
    EXPECT_EQ(fnv1a64Of("b"), 0xaf63df4c8601f1a5ull);
    EXPECT_EQ(fnv1a64Of("c"), 0xaf63de4c8601eff2ull);
    EXPECT_EQ(fnv1a64Of("foobar"), 0x85944171f73967e8ull);
    EXPECT_EQ(fnv1a64Of("chongo was here!\n"), 0x46810940eff5f915ull);
}

TEST(Fnv1a64, ChunksGiveTheHashOfTheWholeStream) {
    constexpr std::string_view kText = "chongo was here!\n";
    for (std::size_t first = 0; first <= kText.size(); ++first) {
        for (std::size_t second = first; second <= kText.size(); ++second) {
            Fnv1a64 hash;
            hash.update(std::as_bytes(std::span(kText.substr(0, first))));
            hash.update(std::as_bytes(std::span(kText.substr(first, second - first))));
            hash.update(std::as_bytes(std::span(kText.substr(second))));
            EXPECT_EQ(hash.value(), fnv1a64Of(kText)) << "split at " << first << ", " << second;
        }
    }
    Fnv1a64 byteByByte;
    for (const std::byte byte : std::as_bytes(std::span(kText))) byteByByte.update(byte);
    EXPECT_EQ(byteByByte.value(), fnv1a64Of(kText));
}

TEST(Fnv1a64, U32IsFedLittleEndian) {
    Fnv1a64 fromInteger;
    fromInteger.updateU32LittleEndian(0x626f6f66u);  // the bytes 'f', 'o', 'o', 'b'
    fromInteger.updateU32LittleEndian(0x00007261u);  // 'a', 'r', then two zero bytes
    EXPECT_EQ(fromInteger.value(), fnv1a64Of(std::string_view("foobar\0\0", 8)));
}

TEST(Fnv1a64, OffsetBasisStartsTheHash) {
    EXPECT_EQ(Fnv1a64(0x1234).value(), 0x1234u);
    // The basis is the state a stream continues from: "foo" then "bar" is "foobar".
    Fnv1a64 bar(fnv1a64Of("foo"));
    bar.update(std::as_bytes(std::span(std::string_view("bar"))));
    EXPECT_EQ(bar.value(), 0x85944171f73967e8ull);
}

TEST(HexDigits, SixteenLowercaseDigitsWithLeadingZeros) {
    EXPECT_EQ(hexDigits(0), "0000000000000000");
    EXPECT_EQ(hexDigits(0x0123456789abcdefull), "0123456789abcdef");
    EXPECT_EQ(hexDigits(0xcbf29ce484222325ull), "cbf29ce484222325");
}

}  // namespace
}  // namespace distile
