import pydicom, numpy as np
from pydicom.uid import ExplicitVRLittleEndian
def crop(src, r0, c0, n, out, signed=False):
    d = pydicom.dcmread(src)
    a = d.pixel_array[r0:r0+n, c0:c0+n].copy()
    if signed:
        a = (a.astype(np.int32) * int(d.RescaleSlope) + int(d.RescaleIntercept)).astype(np.int16)
        d.PixelRepresentation = 1
        d.RescaleIntercept = 0
        d.RescaleSlope = 1
    d.Rows, d.Columns = a.shape
    ipp = [float(x) for x in d.ImagePositionPatient]
    ps = [float(x) for x in d.PixelSpacing]
    o = [float(x) for x in d.ImageOrientationPatient]
    # Move the origin to the crop's first pixel.
    d.ImagePositionPatient = [ipp[i] + c0*ps[1]*o[i] + r0*ps[0]*o[3+i] for i in range(3)]
    d.PixelData = a.tobytes()
    d.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    # Drop private and bulky elements to keep the file small.
    d.remove_private_tags()
    for kw in ['RequestAttributesSequence','ReferencedImageSequence','ProcedureCodeSequence','OtherPatientIDsSequence']:
        if kw in d: del d[kw]
    d.save_as(out, enforce_file_format=True)
    print(out, a.dtype, a.min(), a.max())
crop('/work/shared/data/dicom_mri_brain/1-12.dcm', 120, 100, 48, 'mr_raw.dcm')
crop('/work/shared/data/dicom_ct_lung/1-12.dcm', 200, 200, 48, 'ct_raw.dcm', signed=True)
d = pydicom.dcmread('mr_raw.dcm'); a = d.pixel_array
a8 = np.clip(a // 10, 0, 255).astype(np.uint8)
d.BitsAllocated = 8; d.BitsStored = 8; d.HighBit = 7; d.PixelData = a8.tobytes()
d.save_as('mr8_raw.dcm', enforce_file_format=True)
