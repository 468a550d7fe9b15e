#!/bin/sh
# Remakes the transfer-syntax test set (needs pydicom, numpy, Debian's
# libgdcm-tools for gdcmconv and dcmtk for dcmcjpeg). Crops 48×48 pixels of
# one MR slice (unsigned, 12 bits stored), an 8-bit copy of it, and one CT
# slice stored as signed HU; each is then written in every transfer syntax.
set -e
cd "$(dirname "$0")"
python3 gen.py
gdcmconv --jpeg mr_raw.dcm mr_jpeg70.dcm                 # JPEG Lossless SV1 (.4.70)
dcmcjpeg +ee +q 90 mr8_raw.dcm mr8_jpeg51.dcm            # JPEG Extended 8-bit (.4.51), lossy
dcmcjpeg +ee +q 90 mr_raw.dcm mr12_jpeg51.dcm            # JPEG Extended 12-bit (.4.51): not decoded (jpeg-decoder)
gdcmconv --jpeg --lossy -q 90 mr8_raw.dcm mr8_jpeg50.dcm # JPEG Baseline (.4.50), lossy
gdcmconv --jpegls mr_raw.dcm mr_jls80.dcm                # JPEG-LS lossless (.4.80)
gdcmconv --jpegls --lossy -e 2 mr_raw.dcm mr_jls81.dcm   # JPEG-LS near-lossless (.4.81)
gdcmconv --j2k mr_raw.dcm mr_j2k90.dcm                   # JPEG 2000 lossless (.4.90)
gdcmconv --j2k --lossy -r 4 mr_raw.dcm mr_j2k91.dcm      # JPEG 2000 (.4.91), lossy 4:1 (gdcm decodes it within max 12, rms 3.7)
gdcmconv --rle mr_raw.dcm mr_rle.dcm                     # RLE Lossless (.5)
gdcmconv --deflated mr_raw.dcm mr_deflate.dcm            # Deflated Explicit VR (.1.99)
gdcmconv --jpeg ct_raw.dcm ct_jpeg70.dcm
gdcmconv --j2k ct_raw.dcm ct_j2k90.dcm
gdcmconv --rle ct_raw.dcm ct_rle.dcm
gdcmconv --jpegls ct_raw.dcm ct_jls80.dcm
dcmdjpeg mr8_jpeg51.dcm mr8_jpeg51_dcmdjpeg.dcm                 # dcmtk's own decoding of it (the reference)
