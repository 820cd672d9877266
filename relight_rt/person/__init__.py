"""The person in a photo: masks (the Matter protocol), the bundled matting, the face detector, the face mesh."""
